//! Participating media: homogeneous, or heterogeneous as a density grid scaling the coefficients.
//!
//! A heterogeneous medium has σ_s(x) = d(x)·σ_s and σ_a(x) = d(x)·σ_a with d the trilinearly
//! interpolated density grid (voxel values at voxel centres, zero outside the grid's box). A
//! coarse grid of per-cell density maxima gives the local majorants for delta/ratio tracking.
use crate::Rgb;
use glam::{UVec3, Vec3};

#[derive(Clone, Debug)]
pub struct Medium {
    pub name: String,
    /// Scattering coefficient (1/scene unit), per RGB channel.
    pub sigma_s: Rgb,
    /// Absorption coefficient (1/scene unit), per RGB channel.
    pub sigma_a: Rgb,
    /// Henyey–Greenstein asymmetry, −1 < g < 1.
    pub g: f32,
    /// `None` for a homogeneous medium.
    pub density: Option<DensityGrid>,
}

impl Medium {
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_s + self.sigma_a
    }

    /// Whether light can scatter in the medium at all. One that cannot (σs = 0 in every
    /// channel: a clear region, such as the inside of a clear glass globe in fog) holds no
    /// virtual lights, beams or gather segments: they would carry no light.
    pub fn scatters(&self) -> bool {
        self.sigma_s.max_element() > 0.0
    }

    pub fn is_homogeneous(&self) -> bool {
        self.density.is_none()
    }

    /// Density at `p` (1 for homogeneous media).
    pub fn density_at(&self, p: Vec3) -> f32 {
        self.density.as_ref().map_or(1.0, |g| g.density(p))
    }

    /// [`Medium::density_at`] with `p` clamped into the grid's box: continuous everywhere, for
    /// shaping sampling densities. A point that a rounding error puts just outside the box
    /// (the end of a segment on a wall that is also the grid's bound) gets the box's value,
    /// not 0, so that the GPU, whose points differ from the CPU's by rounding, shapes alike.
    pub fn density_near(&self, p: Vec3) -> f32 {
        self.density.as_ref().map_or(1.0, |g| g.density(p.clamp(g.lo, g.hi)))
    }

    /// The largest of [`Medium::density_near`] at `p` and at the six points `r` away from it
    /// along the axes: a cheap stand-in for the largest density within a sphere of radius `r`
    /// about `p`, for shaping the sampling of VSL centres whose light scatters anywhere in it.
    pub fn density_within(&self, p: Vec3, r: f32) -> f32 {
        if self.density.is_none() {
            return 1.0;
        }
        let mut best = self.density_near(p);
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            best = best
                .max(self.density_near(p + axis * r))
                .max(self.density_near(p - axis * r));
        }
        best
    }
}

/// Voxels per majorant cell along each axis.
pub const MAJORANT_BLOCK: u32 = 8;

/// A scalar density grid over an axis-aligned box, with its majorant grid.
#[derive(Clone, Debug)]
pub struct DensityGrid {
    pub res: UVec3,
    pub lo: Vec3,
    pub hi: Vec3,
    /// `res.x * res.y * res.z` non-negative finite values, x fastest, then y, then z.
    pub values: Vec<f32>,
    /// Resolution of the majorant grid (`ceil(res / MAJORANT_BLOCK)`).
    pub majorant_res: UVec3,
    /// Upper bound of the density anywhere inside each majorant cell.
    pub majorants: Vec<f32>,
}

impl DensityGrid {
    /// Builds a grid; `values` must hold `res.x*res.y*res.z` finite, non-negative numbers and
    /// the box must be non-empty (the loader checks and reports both).
    pub fn new(res: UVec3, lo: Vec3, hi: Vec3, values: Vec<f32>) -> Self {
        assert_eq!(values.len(), (res.x * res.y * res.z) as usize);
        let majorant_res = (res + UVec3::splat(MAJORANT_BLOCK - 1)) / MAJORANT_BLOCK;
        let mut majorants = vec![0.0f32; (majorant_res.x * majorant_res.y * majorant_res.z) as usize];
        let at = |x: u32, y: u32, z: u32| values[(x + res.x * (y + res.y * z)) as usize];
        for cz in 0..majorant_res.z {
            for cy in 0..majorant_res.y {
                for cx in 0..majorant_res.x {
                    // Trilinear interpolation anywhere in the cell reads voxels up to one voxel
                    // beyond the cell's own block, so the bound includes that one-voxel rim.
                    let range = |c: u32, n: u32| {
                        let a = (c * MAJORANT_BLOCK).saturating_sub(1);
                        let b = ((c + 1) * MAJORANT_BLOCK).min(n - 1);
                        a..=b
                    };
                    let mut m = 0.0f32;
                    for z in range(cz, res.z) {
                        for y in range(cy, res.y) {
                            for x in range(cx, res.x) {
                                m = m.max(at(x, y, z));
                            }
                        }
                    }
                    majorants[(cx + majorant_res.x * (cy + majorant_res.y * cz)) as usize] = m;
                }
            }
        }
        Self {
            res,
            lo,
            hi,
            values,
            majorant_res,
            majorants,
        }
    }

    /// A grid of constant density (useful for tests: it must match the homogeneous medium).
    pub fn constant(res: UVec3, lo: Vec3, hi: Vec3, value: f32) -> Self {
        Self::new(res, lo, hi, vec![value; (res.x * res.y * res.z) as usize])
    }

    #[inline]
    fn voxel(&self, x: u32, y: u32, z: u32) -> f32 {
        self.values[(x + self.res.x * (y + self.res.y * z)) as usize]
    }

    /// Trilinearly interpolated density; zero outside the box.
    pub fn density(&self, p: Vec3) -> f32 {
        if p.cmplt(self.lo).any() || p.cmpgt(self.hi).any() {
            return 0.0;
        }
        let resf = self.res.as_vec3();
        // Continuous voxel coordinate with voxel centres at integers.
        let u = (p - self.lo) / (self.hi - self.lo) * resf - Vec3::splat(0.5);
        let max = resf - Vec3::ONE;
        let u = u.clamp(Vec3::ZERO, max);
        // u ≥ 0 (NaN becomes 0 either way): the cast's truncation is the floor, without a
        // libm `floorf` call per axis on CPUs the build cannot assume SSE4.1 on (5 % of a
        // smoke box `Lmm` render).
        let i0 = u.as_uvec3();
        let f = u - i0.as_vec3();
        let i1 = (i0 + UVec3::ONE).min(self.res - UVec3::ONE);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(self.voxel(i0.x, i0.y, i0.z), self.voxel(i1.x, i0.y, i0.z), f.x);
        let c10 = lerp(self.voxel(i0.x, i1.y, i0.z), self.voxel(i1.x, i1.y, i0.z), f.x);
        let c01 = lerp(self.voxel(i0.x, i0.y, i1.z), self.voxel(i1.x, i0.y, i1.z), f.x);
        let c11 = lerp(self.voxel(i0.x, i1.y, i1.z), self.voxel(i1.x, i1.y, i1.z), f.x);
        lerp(lerp(c00, c10, f.y), lerp(c01, c11, f.y), f.z)
    }

    /// World-space size of one majorant cell.
    pub fn majorant_cell_size(&self) -> Vec3 {
        (self.hi - self.lo) / self.res.as_vec3() * MAJORANT_BLOCK as f32
    }

    /// Majorant of the cell with integer coordinates `c` (must be inside the majorant grid).
    #[inline]
    pub fn majorant(&self, c: UVec3) -> f32 {
        self.majorants[(c.x + self.majorant_res.x * (c.y + self.majorant_res.y * c.z)) as usize]
    }

    /// Largest density anywhere.
    pub fn max_density(&self) -> f32 {
        self.majorants.iter().copied().fold(0.0, f32::max)
    }
}

/// Raw density grid file (`.bgrid`): the 8 bytes `BLGRID01`, then `nx ny nz` as little-endian
/// u32, then `nx*ny*nz` little-endian f32 values, x fastest. The box it fills is given in the
/// scene sidecar.
pub const GRID_MAGIC: &[u8; 8] = b"BLGRID01";

/// Parses a `.bgrid` file's bytes into `(resolution, values)`; the error says what is wrong.
pub fn parse_grid(bytes: &[u8]) -> Result<(UVec3, Vec<f32>), String> {
    if bytes.len() < 20 || &bytes[..8] != GRID_MAGIC {
        return Err("not a beamlight density grid (expected the 8-byte magic BLGRID01 and a 12-byte header)".into());
    }
    let word = |i: usize| u32::from_le_bytes(bytes[8 + 4 * i..12 + 4 * i].try_into().unwrap());
    let res = UVec3::new(word(0), word(1), word(2));
    if res.min_element() == 0 || res.max_element() > 4096 {
        return Err(format!(
            "grid resolution {}x{}x{} must be between 1 and 4096 per axis",
            res.x, res.y, res.z
        ));
    }
    let n = res.x as usize * res.y as usize * res.z as usize;
    let body = &bytes[20..];
    if body.len() != 4 * n {
        return Err(format!(
            "grid {}x{}x{} needs {} bytes of values, file has {}",
            res.x,
            res.y,
            res.z,
            4 * n,
            body.len()
        ));
    }
    let values: Vec<f32> = body
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite() || *v < 0.0) {
        return Err(format!(
            "grid value #{i} is {}; densities must be finite and non-negative",
            values[i]
        ));
    }
    Ok((res, values))
}

/// Serializes a grid in the `.bgrid` format.
pub fn write_grid(res: UVec3, values: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(20 + 4 * values.len());
    out.extend_from_slice(GRID_MAGIC);
    for w in [res.x, res.y, res.z] {
        out.extend_from_slice(&w.to_le_bytes());
    }
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trilinear_reproduces_linear_field_and_majorants_bound_it() {
        let res = UVec3::new(20, 9, 5);
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 1.0, 3.0));
        let cell = (hi - lo) / res.as_vec3();
        let mut values = Vec::new();
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let c = lo + (UVec3::new(x, y, z).as_vec3() + 0.5) * cell;
                    values.push(1.0 + c.x + 2.0 * c.y + 0.5 * c.z + ((x * 7 + y * 3) % 5) as f32 * 0.0);
                }
            }
        }
        let g = DensityGrid::new(res, lo, hi, values);
        // Interior point: linear field is reproduced exactly by trilinear interpolation.
        let p = Vec3::new(0.77, 0.41, 2.52);
        assert!((g.density(p) - (1.0 + p.x + 2.0 * p.y + 0.5 * p.z)).abs() < 1e-4);
        assert_eq!(g.density(Vec3::new(5.0, 0.5, 2.5)), 0.0);
        // Majorants bound the density on a dense set of points.
        let cs = g.majorant_cell_size();
        for i in 0..4000 {
            let t = Vec3::new(
                (i % 17) as f32 / 16.0,
                (i / 17 % 13) as f32 / 12.0,
                (i / 221) as f32 / 18.0,
            );
            let p = lo + t.min(Vec3::splat(0.99999)) * (hi - lo);
            let c = ((p - lo) / cs).floor().as_uvec3().min(g.majorant_res - UVec3::ONE);
            assert!(g.density(p) <= g.majorant(c) + 1e-5);
        }
    }

    #[test]
    fn grid_file_round_trip_and_errors() {
        let res = UVec3::new(2, 3, 1);
        let vals = vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let bytes = write_grid(res, &vals);
        assert_eq!(parse_grid(&bytes).unwrap(), (res, vals));
        assert!(
            parse_grid(&bytes[..bytes.len() - 1])
                .unwrap_err()
                .contains("needs 24 bytes")
        );
        assert!(parse_grid(b"hello").is_err());
        let mut bad = write_grid(res, &[0.0, 1.0, f32::NAN, 3.0, 4.0, 5.0]);
        assert!(parse_grid(&bad).unwrap_err().contains("#2"));
        bad[8] = 0;
        assert!(parse_grid(&bad).is_err());
    }
}
