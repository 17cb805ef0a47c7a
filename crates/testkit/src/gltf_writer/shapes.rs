//! Simple closed and open shapes as indexed triangle lists (counter-clockwise = front).
use glam::Vec3;

/// The parallelogram `corner`, `corner+u`, `corner+u+v`, `corner+v`; its normal is `u × v`.
pub fn quad(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> (Vec<Vec3>, Vec<u32>) {
    let p = vec![corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v];
    (p, vec![0, 1, 2, 0, 2, 3])
}

/// The closed axis-aligned box `[lo, hi]` (8 shared vertices, 12 triangles), normals pointing
/// out of the box when `outward_normals`, into it otherwise.
pub fn cuboid(lo: Vec3, hi: Vec3, outward_normals: bool) -> (Vec<Vec3>, Vec<u32>) {
    let c = |i: u32| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let positions: Vec<Vec3> = (0..8).map(c).collect();
    // Each face as a quad a-b-c-d, counter-clockwise seen from outside.
    let faces: [[u32; 4]; 6] = [
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
    ];
    let mut indices = Vec::with_capacity(36);
    for [a, b, c, d] in faces {
        if outward_normals {
            indices.extend_from_slice(&[a, b, c, a, c, d]);
        } else {
            indices.extend_from_slice(&[a, c, b, a, d, c]);
        }
    }
    (positions, indices)
}

/// A closed UV sphere with outward normals: poles on ±Y, `rings ≥ 2` latitude bands and
/// `segments ≥ 3` longitude slices. Vertex normals are `(p − center) / radius`.
pub fn uv_sphere(center: Vec3, radius: f32, rings: u32, segments: u32) -> (Vec<Vec3>, Vec<u32>) {
    assert!(
        rings >= 2 && segments >= 3,
        "uv_sphere needs rings >= 2 and segments >= 3"
    );
    let mut p = vec![center + Vec3::Y * radius];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        let (st, ct) = theta.sin_cos();
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let (sp, cp) = phi.sin_cos();
            p.push(center + Vec3::new(st * cp, ct, -st * sp) * radius);
        }
    }
    p.push(center - Vec3::Y * radius);
    let bottom = p.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut idx = Vec::new();
    for s in 0..segments {
        idx.extend_from_slice(&[0, ring(1, s), ring(1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1));
            idx.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    for s in 0..segments {
        idx.extend_from_slice(&[bottom, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    (p, idx)
}

/// Appends mesh `b` to mesh `a` (indices offset).
pub fn merge(a: &mut (Vec<Vec3>, Vec<u32>), b: (Vec<Vec3>, Vec<u32>)) {
    let off = a.0.len() as u32;
    a.0.extend(b.0);
    a.1.extend(b.1.into_iter().map(|i| i + off));
}
