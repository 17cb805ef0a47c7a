//! beamlight-render: the orchestrator. It owns the progressive loop (pass after pass until a
//! budget runs out), the per-pixel accumulators, and image input/output.
//!
//! Data flows one way: scene → tracing → estimators → accumulators ([`film`]) → image ([`output`]).
pub mod accum;
pub mod auto;
pub mod backend;
pub mod combine;
pub mod compare;
pub mod components;
pub mod film;
pub mod many_lights;
pub mod memory;
pub mod method;
pub mod options;
pub mod output;
pub mod progressive;
pub mod radius;
mod record_gathers;
pub mod schedule;
pub mod sheet;
pub mod source;

// The types of the render API that other crates define: the scene a render traces, and the
// estimators' settings inside `RenderOptions`.
pub use beamlight_trace::{TraceScene, light_tree::Drawing, pt::PathTracerSettings, vbl::VblSettings};
pub use film::{Film, Image};
pub use method::Method;
pub use options::{Budget, RenderOptions};
pub use progressive::{Progress, RenderResult, render, render_from};
