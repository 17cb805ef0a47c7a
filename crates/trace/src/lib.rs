//! beamlight-trace: the CPU side of rendering — BVH and ray queries, transmittance and
//! distance sampling in media, light sampling, and the reference volumetric path tracer.
pub mod bvh;
pub mod camera_paths;
pub mod caustics;
pub mod components;
pub mod context;
pub mod direct;
pub mod failed;
pub mod gather;
pub mod geometry;
pub mod light_paths;
pub mod light_tree;
pub mod lights;
pub mod media;
pub mod patches;
pub mod pt;
pub mod spatial;
pub mod streams;
pub mod vbl;
pub mod vpl;
pub mod vrl;

pub use context::TraceScene;
