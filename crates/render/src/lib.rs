//! beamlight-render: the orchestrator. It owns the progressive loop (pass after pass until a
//! budget runs out), the per-pixel accumulators, and image input/output.
//!
//! Data flows one way: scene → tracing → estimators → accumulators ([`film`]) → image ([`output`]).
pub mod accum;
pub mod auto;
pub mod compare;
pub mod components;
pub mod film;
pub mod many_lights;
pub mod output;
pub mod progressive;
pub mod radius;
pub mod sheet;

pub use film::{Film, Image};
pub use progressive::{Budget, Method, Progress, RenderOptions, RenderResult, render, render_from};
