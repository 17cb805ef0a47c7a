//! OpenVDB density grids, read with the `vdb-rs` crate and resampled into a dense
//! [`crate::medium::DensityGrid`].
//!
//! Supported: float grids (`Tree_float_5_4_3`, also when saved as half floats), file format
//! versions 222–224 (OpenVDB 6–11+ writers), Blosc, zlib or no compression, active voxels and
//! active internal-node tiles, `UniformScaleMap`, `UniformScaleTranslateMap` and
//! `ScaleTranslateMap` transforms with positive scale (the axis-aligned ones; a dense grid is
//! axis-aligned). Not supported (a clear error, never a crash): other grid types (vectors,
//! doubles, level-set-like negative values), affine/rotating/frustum maps, older files, point
//! grids. Root-level tiles (each 4096³ voxels) are not read by `vdb-rs` and the background is
//! taken as 0 (the fog-volume convention); both are documented limitations.
//!
//! Resampling is exact: every VDB voxel becomes one dense voxel. In index space a VDB voxel's
//! value sits at its integer coordinate; the dense grid covers the active voxels' index box
//! `[min, max]` plus one voxel of background on every side (so trilinear interpolation fades to
//! 0 over one voxel past the last active voxel, as OpenVDB's box sampler does), and its world
//! box is the index box `[min − 1.5, max + 1.5]` mapped through the grid's transform
//! `x_world = scale ⊙ x_index + translation`. The dense voxel centres are then exactly the VDB
//! voxel positions.
use glam::{DVec3, IVec3, UVec3};
use std::io::Cursor;
use std::panic::{AssertUnwindSafe, catch_unwind};
use vdb_rs::{Map, VdbLevel, VdbReader};

/// Largest dense grid a VDB (or procedural density) may expand to: 2²⁴ voxels (256³,
/// 64 MiB of f32), well inside the GPU's 128 MiB storage-binding limit.
pub const MAX_DENSE_VOXELS: u64 = 1 << 24;

/// A VDB float grid expanded to a dense block.
#[derive(Clone, Debug)]
pub struct VdbDensity {
    /// Dense resolution: the active index box plus one voxel of padding on each side.
    pub res: UVec3,
    /// Dense values, x fastest; voxel `i` holds VDB index `index_min − 1 + i`.
    pub values: Vec<f32>,
    /// Inclusive index box of the active voxels (tiles expanded).
    pub index_min: IVec3,
    pub index_max: IVec3,
    /// Number of active voxels (tiles counted voxel by voxel).
    pub active_voxels: u64,
    /// The transform: `world = scale * index + translation`.
    pub scale: DVec3,
    pub translation: DVec3,
}

impl VdbDensity {
    /// World position of an index-space point.
    pub fn index_to_world(&self, ijk: DVec3) -> DVec3 {
        self.scale * ijk + self.translation
    }

    /// The dense grid's world box (`[min − 1.5, max + 1.5]` in index space, transformed).
    pub fn world_box(&self) -> (DVec3, DVec3) {
        (
            self.index_to_world(self.index_min.as_dvec3() - DVec3::splat(1.5)),
            self.index_to_world(self.index_max.as_dvec3() + DVec3::splat(1.5)),
        )
    }

    /// The dense grid's box when the active voxels' outer faces (index `[min − 0.5,
    /// max + 0.5]`) are placed at `[lo, hi]` instead (the sidecar's `bounds`).
    pub fn box_for_bounds(&self, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
        let cells = (self.index_max - self.index_min + IVec3::ONE).as_dvec3();
        let cell = (hi - lo) / cells;
        (lo - cell, hi + cell)
    }
}

const VDB_MAGIC: u32 = 0x5644_4220;

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown reason".into())
}

/// Reads grid `name` from the bytes of a `.vdb` file. Errors say what is wrong (and list the
/// grids present when `name` is not one of them).
pub fn read_vdb(bytes: &[u8], name: &str) -> Result<VdbDensity, String> {
    if bytes.len() < 8 || u32::from_le_bytes(bytes[..4].try_into().unwrap()) != VDB_MAGIC {
        return Err("not an OpenVDB file (it does not start with the VDB magic number)".into());
    }
    let version = bytes.get(8..12).map(|b| u32::from_le_bytes(b.try_into().unwrap()));
    if let Some(v) = version
        && !(222..=224).contains(&v)
    {
        return Err(format!(
            "OpenVDB file format version {v} is not supported (supported: 222 to 224, written by OpenVDB 6 and later)"
        ));
    }
    let broken = |what: String| format!("corrupt or truncated OpenVDB file ({what})");
    let mut reader = match catch_unwind(AssertUnwindSafe(|| VdbReader::new(Cursor::new(bytes)))) {
        Ok(Ok(r)) => r,
        Ok(Err(e)) => return Err(broken(format!("header: {e}"))),
        Err(p) => return Err(broken(format!("header: {}", panic_text(&*p)))),
    };
    // A file cut short after the wanted grid still parses; its index says where grids end.
    if let Some(d) = reader
        .grid_descriptors
        .values()
        .find(|d| d.end_pos > bytes.len() as u64)
    {
        return Err(format!(
            "truncated OpenVDB file: grid '{}' ends at byte {}, the file has {} bytes",
            d.name,
            d.end_pos,
            bytes.len()
        ));
    }
    let mut names = reader.available_grids();
    names.sort();
    let Some(desc) = reader.grid_descriptors.get(name) else {
        let list = if names.is_empty() {
            "the file has no grids".to_string()
        } else {
            format!(
                "grids: {}",
                names.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
            )
        };
        return Err(format!("no grid named '{name}' ({list})"));
    };
    let ty = desc.grid_type.clone();
    if !ty.starts_with("Tree_float_") {
        let value = ty
            .strip_prefix("Tree_")
            .and_then(|t| t.split('_').next())
            .unwrap_or(&ty);
        return Err(format!(
            "grid '{name}' holds {value} values ({ty}); a density must be a float grid"
        ));
    }
    if ty != "Tree_float_5_4_3" {
        return Err(format!(
            "grid '{name}' has the tree configuration {ty}; only the standard Tree_float_5_4_3 is supported"
        ));
    }
    let grid = match catch_unwind(AssertUnwindSafe(|| reader.read_grid::<f32>(name))) {
        Ok(Ok(g)) => g,
        Ok(Err(e)) => return Err(broken(format!("grid '{name}': {e}"))),
        Err(p) => return Err(broken(format!("grid '{name}': {}", panic_text(&*p)))),
    };
    let (scale, translation) = match &grid.transform {
        Map::UniformScaleMap { scale_values: s, .. } => (DVec3::new(s.x, s.y, s.z), DVec3::ZERO),
        Map::ScaleTranslateMap {
            scale_values: s,
            translation: t,
            ..
        } => (DVec3::new(s.x, s.y, s.z), DVec3::new(t.x, t.y, t.z)),
    };
    if !(scale.is_finite() && translation.is_finite() && scale.min_element() > 0.0) {
        return Err(format!(
            "grid '{name}': the transform (voxel size {scale}, translation {translation}) must be finite with a positive scale on every axis"
        ));
    }
    // Active voxels and tiles: (origin, edge length in voxels, value).
    let items: Vec<(IVec3, i32, f32)> = match catch_unwind(AssertUnwindSafe(|| {
        grid.iter()
            .map(|(c, v, level)| {
                let edge = match level {
                    VdbLevel::Voxel => 1,
                    VdbLevel::Node3 => 8,
                    VdbLevel::Node4 => 128,
                };
                (IVec3::new(c.x as i32, c.y as i32, c.z as i32), edge, v)
            })
            .collect()
    })) {
        Ok(items) => items,
        Err(p) => return Err(broken(format!("grid '{name}': {}", panic_text(&*p)))),
    };
    if items.is_empty() {
        return Err(format!("grid '{name}' has no active voxels"));
    }
    let (mut lo, mut hi) = (IVec3::MAX, IVec3::MIN);
    let mut active = 0u64;
    for &(c, edge, v) in &items {
        if !(v.is_finite() && v >= 0.0) {
            return Err(format!(
                "grid '{name}': the voxel at index ({}, {}, {}) holds {v}; densities must be finite and non-negative",
                c.x, c.y, c.z
            ));
        }
        lo = lo.min(c);
        hi = hi.max(c + IVec3::splat(edge - 1));
        active += (edge as u64).pow(3);
    }
    let dims = (hi - lo).as_i64vec3() + glam::I64Vec3::splat(3);
    let total = dims.x as u64 * dims.y as u64 * dims.z as u64;
    if total > MAX_DENSE_VOXELS {
        return Err(format!(
            "grid '{name}': its active voxels span {} x {} x {} voxels with padding, more than the {MAX_DENSE_VOXELS} a dense density grid may hold",
            dims.x, dims.y, dims.z
        ));
    }
    let res = UVec3::new(dims.x as u32, dims.y as u32, dims.z as u32);
    let mut values = vec![0.0f32; total as usize];
    let origin = lo - IVec3::ONE;
    for &(c, edge, v) in &items {
        for z in 0..edge {
            for y in 0..edge {
                for x in 0..edge {
                    let d = (c + IVec3::new(x, y, z) - origin).as_uvec3();
                    values[(d.x + res.x * (d.y + res.y * d.z)) as usize] = v;
                }
            }
        }
    }
    Ok(VdbDensity {
        res,
        values,
        index_min: lo,
        index_max: hi,
        active_voxels: active,
        scale,
        translation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::DensityGrid;

    fn blob() -> Vec<u8> {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/volumes/blob.vdb");
        std::fs::read(path).expect("assets/volumes/blob.vdb")
    }

    /// The facts below are what OpenVDB 10.0.1 reported when it wrote the file
    /// (`assets/volumes/make_test_vdb.py`; see assets/README.md).
    #[test]
    fn reads_the_test_volume_as_openvdb_wrote_it() {
        let v = read_vdb(&blob(), "density").unwrap();
        assert_eq!(v.index_min, IVec3::new(-6, 0, -4));
        assert_eq!(v.index_max, IVec3::new(23, 11, 7));
        assert_eq!(v.active_voxels, 1520);
        assert_eq!(v.res, UVec3::new(32, 14, 14));
        assert!((v.scale - DVec3::new(0.1, 0.05, 0.08)).abs().max_element() < 1e-12);
        assert!((v.translation - DVec3::new(0.2, -0.1, -0.3)).abs().max_element() < 1e-12);
        let at = |i: i32, j: i32, k: i32| {
            let d = (IVec3::new(i, j, k) - v.index_min + IVec3::ONE).as_uvec3();
            v.values[(d.x + v.res.x * (d.y + v.res.y * d.z)) as usize]
        };
        for (ijk, value) in [
            ((1, 5, 0), 1.223_9),
            ((2, 6, 1), 1.272_9),
            ((-6, 5, 0), 0.130_2),
            ((9, 5, 0), 0.130_2),
            ((1, 0, 0), 0.145_8),
            ((20, 3, 4), 0.25), // inside the active tile
            ((10, 5, 0), 0.0),  // inactive: background
            ((0, 11, 5), 0.0),
        ] {
            assert!((at(ijk.0, ijk.1, ijk.2) - value).abs() < 1e-6, "{ijk:?}");
        }
        let max = v.values.iter().copied().fold(0.0, f32::max);
        assert!((max - 1.272_9).abs() < 1e-6);
        assert_eq!(v.values.iter().filter(|x| **x > 0.0).count(), 1520);

        // World placement: OpenVDB's indexToWorld((1,5,0)) = (0.3, 0.15, -0.3) and
        // ((20,3,4)) = (2.2, 0.05, 0.02); the dense grid reproduces the voxel values there.
        let (lo, hi) = v.world_box();
        assert!(
            (lo - DVec3::new(0.2 - 0.75, -0.1 - 0.075, -0.3 - 0.44))
                .abs()
                .max_element()
                < 1e-9
        );
        assert!(
            (hi - DVec3::new(0.2 + 2.45, -0.1 + 0.625, -0.3 + 0.68))
                .abs()
                .max_element()
                < 1e-9
        );
        let g = DensityGrid::new(v.res, lo.as_vec3(), hi.as_vec3(), v.values.clone());
        let w = |p: [f64; 3]| DVec3::from(p).as_vec3();
        assert!((g.density(w([0.3, 0.15, -0.3])) - 1.223_9).abs() < 1e-4);
        assert!((g.density(w([2.2, 0.05, 0.02])) - 0.25).abs() < 1e-4);
        // Halfway between two voxels: their mean (trilinear, as OpenVDB's box sampler).
        let mid = g.density(w([0.35, 0.15, -0.3]));
        assert!((mid - 0.5 * (at(1, 5, 0) + at(2, 5, 0))).abs() < 1e-4);
        // Outside the padded box: nothing.
        assert_eq!(g.density(w([3.0, 0.0, 0.0])), 0.0);
        // `bounds` places the active voxels' outer faces.
        let (blo, bhi) = v.box_for_bounds(DVec3::ZERO, DVec3::new(3.0, 1.2, 1.2));
        assert!((blo - DVec3::new(-0.1, -0.1, -0.1)).abs().max_element() < 1e-12);
        assert!((bhi - DVec3::new(3.1, 1.3, 1.3)).abs().max_element() < 1e-12);
    }

    #[test]
    fn errors_name_the_problem() {
        let bytes = blob();
        let e = read_vdb(&bytes, "smoke").unwrap_err();
        assert!(
            e.contains("no grid named 'smoke' (grids: 'density', 'temperature', 'velocity')"),
            "{e}"
        );
        let e = read_vdb(&bytes, "velocity").unwrap_err();
        assert!(e.contains("vec3s") && e.contains("float grid"), "{e}");
        assert_eq!(read_vdb(&bytes, "temperature").unwrap().active_voxels, 1);
        assert!(
            read_vdb(b"hello world", "density")
                .unwrap_err()
                .contains("not an OpenVDB file")
        );
        // Truncated anywhere: an error, never a panic.
        for k in 1..200 {
            let len = bytes.len() * k / 200;
            assert!(read_vdb(&bytes[..len], "density").is_err(), "{len}");
        }
    }
}
