//! Sampling routines shared by every integrator. (Stub: being implemented.)
use glam::{Vec2, Vec3};

pub fn uniform_sphere(u: Vec2) -> Vec3 { todo!("{u}") }
pub fn cosine_hemisphere(u: Vec2) -> Vec3 { todo!("{u}") }
/// Barycentrics (b1, b2) uniform over a triangle.
pub fn uniform_triangle(u: Vec2) -> Vec2 { todo!("{u}") }
pub fn power_heuristic(f_pdf: f32, g_pdf: f32) -> f32 { todo!("{f_pdf}{g_pdf}") }

/// Piecewise-constant 1-D distribution over `n` discrete items.
#[derive(Clone, Debug)]
pub struct Distribution1D { pub cdf: Vec<f32>, pub total: f32 }
impl Distribution1D {
    pub fn new(weights: &[f32]) -> Self { todo!("{weights:?}") }
    /// Returns (index, probability of that index).
    pub fn sample(&self, u: f32) -> (usize, f32) { todo!("{u}") }
    pub fn pmf(&self, i: usize) -> f32 { todo!("{i}") }
    pub fn len(&self) -> usize { self.cdf.len().saturating_sub(1) }
    pub fn is_empty(&self) -> bool { self.len() == 0 }
}
