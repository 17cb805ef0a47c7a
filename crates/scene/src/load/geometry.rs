//! What building the triangles hands to the media code: the scene's triangles and the
//! instances of medium regions among them.
use crate::scene::Triangle;
use glam::Vec3;
use std::ops::Range;

/// Triangles of the scene plus, for medium regions, what the media code needs.
pub(super) struct Geometry {
    pub triangles: Vec<Triangle>,
    pub regions: Vec<RegionInstance>,
}

/// One instance (node) of a mesh that bounds a medium.
pub(super) struct RegionInstance {
    /// Index into the planned media.
    pub medium: usize,
    pub mesh: usize,
    pub node: usize,
    /// Its (non-degenerate) triangles in [`Geometry::triangles`].
    pub tris: Range<usize>,
    /// All its world-space triangles, degenerate ones included, for the topology checks.
    pub raw: Vec<[Vec3; 3]>,
}
