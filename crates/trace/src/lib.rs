//! CPU tracing
