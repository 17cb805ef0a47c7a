//! Mesh primitives to world-space triangles with their materials, shading normals and
//! texture coordinates, and the instances of medium regions.
use super::Src;
use super::geometry::{Geometry, RegionInstance};
use super::gltf_read::GltfDoc;
use super::materials::DEFAULT_ALBEDO;
use super::media::MediaPlan;
use super::names::{material_label, mesh_label, node_label};
use super::nodes::Traversal;
use crate::SceneError;
use crate::bsdf::{Bsdf, Material};
use crate::scene::Triangle;
use glam::{Mat3, Vec2, Vec3};
use gltf::json::{mesh::Mode, mesh::Semantic, validation::Checked};

pub(super) fn build_triangles(
    src: &Src,
    doc: &GltfDoc,
    trav: &Traversal,
    plan: &MediaPlan,
    materials: &mut Vec<Material>,
    tex_coord: &[Option<u32>],
    warnings: &mut Vec<String>,
) -> Result<Geometry, SceneError> {
    let root = &doc.root;
    let f = src.name();
    let mut default_material: Option<u32> = None;
    let mut boundary_material: Option<u32> = None;
    let mut degenerate = vec![0usize; root.meshes.len()];
    let mut warned_mode = vec![false; root.meshes.len()];
    let mut triangles = Vec::new();
    let mut regions = Vec::new();

    // Each mesh's primitives are decoded once, then instanced.
    struct Prim {
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        /// Only for primitives whose material has a base-colour texture.
        uvs: Option<Vec<Vec2>>,
        tris: Vec<[u32; 3]>,
        material: Option<usize>,
    }
    let mut decoded: Vec<Option<Vec<Prim>>> = (0..root.meshes.len()).map(|_| None).collect();

    for &(node, mesh_i, world) in &trav.instances {
        if decoded[mesh_i].is_none() {
            let mesh = &root.meshes[mesh_i];
            let mlabel = mesh_label(root, mesh_i);
            let mut prims = Vec::new();
            for (pi, p) in mesh.primitives.iter().enumerate() {
                let what = format!("{mlabel} primitive {pi}");
                let mode = match p.mode {
                    Checked::Valid(m) => m,
                    Checked::Invalid => return Err(src.err(format!("{what}: invalid mode"))),
                };
                if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                    if !std::mem::replace(&mut warned_mode[mesh_i], true) {
                        warnings.push(format!("{f}: {what}: mode {mode:?} is not triangles; skipped"));
                    }
                    continue;
                }
                let Some(pos_acc) = p.attributes.get(&Checked::Valid(Semantic::Positions)) else {
                    warnings.push(format!("{f}: {what}: no POSITION attribute; skipped"));
                    continue;
                };
                let positions: Vec<Vec3> = doc
                    .read_vec3(src, &format!("{what} POSITION"), pos_acc.value())?
                    .into_iter()
                    .map(Vec3::from)
                    .collect();
                if let Some(v) = positions.iter().position(|p| !p.is_finite()) {
                    return Err(src.err(format!("{what}: vertex {v} has a non-finite position {}", positions[v])));
                }
                let normals = match p.attributes.get(&Checked::Valid(Semantic::Normals)) {
                    Some(acc) => {
                        let n: Vec<Vec3> = doc
                            .read_vec3(src, &format!("{what} NORMAL"), acc.value())?
                            .into_iter()
                            .map(Vec3::from)
                            .collect();
                        if n.len() != positions.len() {
                            return Err(src.err(format!(
                                "{what}: NORMAL has {} elements but POSITION has {}",
                                n.len(),
                                positions.len()
                            )));
                        }
                        if let Some(v) = n.iter().position(|p| !p.is_finite()) {
                            return Err(src.err(format!("{what}: vertex {v} has a non-finite normal {}", n[v])));
                        }
                        Some(n)
                    }
                    None => None,
                };
                let uvs = match p.material.and_then(|m| tex_coord.get(m.value()).copied().flatten()) {
                    None => None,
                    Some(set) => match p.attributes.get(&Checked::Valid(Semantic::TexCoords(set))) {
                        Some(acc) => {
                            let uv: Vec<Vec2> = doc
                                .read_texcoords(src, &format!("{what} TEXCOORD_{set}"), acc.value())?
                                .into_iter()
                                .map(Vec2::from)
                                .collect();
                            if uv.len() != positions.len() {
                                return Err(src.err(format!(
                                    "{what}: TEXCOORD_{set} has {} elements but POSITION has {}",
                                    uv.len(),
                                    positions.len()
                                )));
                            }
                            if let Some(v) = uv.iter().position(|t| !t.is_finite()) {
                                return Err(
                                    src.err(format!("{what}: vertex {v} has a non-finite TEXCOORD_{set} {}", uv[v]))
                                );
                            }
                            Some(uv)
                        }
                        None => {
                            // What WebGL viewers do: a missing attribute reads as (0, 0).
                            warnings.push(format!(
                                "{f}: {what}: no TEXCOORD_{set} for the base colour texture of {}; uv (0, 0) is used",
                                material_label(root, p.material.map_or(0, |m| m.value()))
                            ));
                            Some(vec![Vec2::ZERO; positions.len()])
                        }
                    },
                };
                let indices: Vec<u32> = match p.indices {
                    Some(acc) => doc.read_indices(src, &format!("{what} indices"), acc.value())?,
                    None => (0..positions.len() as u32).collect(),
                };
                if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(src.err(format!(
                        "{what}: index {bad} out of range ({} vertices)",
                        positions.len()
                    )));
                }
                let tris: Vec<[u32; 3]> = match mode {
                    Mode::Triangles => {
                        if !indices.len().is_multiple_of(3) {
                            return Err(src.err(format!(
                                "{what}: {} {} is not a multiple of 3",
                                indices.len(),
                                if p.indices.is_some() { "indices" } else { "vertices" }
                            )));
                        }
                        indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
                    }
                    Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                        .map(|k| {
                            if k % 2 == 0 {
                                [indices[k], indices[k + 1], indices[k + 2]]
                            } else {
                                [indices[k], indices[k + 2], indices[k + 1]]
                            }
                        })
                        .collect(),
                    _ => (1..indices.len().saturating_sub(1))
                        .map(|k| [indices[0], indices[k], indices[k + 1]])
                        .collect(),
                };
                prims.push(Prim {
                    positions,
                    normals,
                    uvs,
                    tris,
                    material: p.material.map(|m| m.value()),
                });
            }
            decoded[mesh_i] = Some(prims);
        }
        let prims = decoded[mesh_i].as_ref().expect("decoded above");
        let region = plan.region_of_mesh[mesh_i];

        let lin = Mat3::from_mat4(world);
        let det = lin.determinant();
        if !(det.abs() > 1e-30) || !det.is_finite() {
            warnings.push(format!(
                "{f}: {} has a singular transform (zero scale); its {} is skipped",
                node_label(root, node),
                mesh_label(root, mesh_i)
            ));
            continue;
        }
        let normal_matrix = lin.inverse().transpose();
        let flip = det < 0.0;
        let first = triangles.len();
        let mut raw = Vec::new();
        for prim in prims {
            let material = match (prim.material, region) {
                (Some(m), _) => m as u32,
                (None, Some(_)) => *boundary_material.get_or_insert_with(|| {
                    materials.push(Material {
                        name: "<medium boundary>".into(),
                        bsdf: None,
                        emission: Vec3::ZERO,
                        double_sided: false,
                        base_color_texture: None,
                    });
                    (materials.len() - 1) as u32
                }),
                (None, None) => *default_material.get_or_insert_with(|| {
                    materials.push(Material {
                        name: "<default>".into(),
                        bsdf: Some(Bsdf::Lambert {
                            albedo: Vec3::splat(DEFAULT_ALBEDO),
                        }),
                        emission: Vec3::ZERO,
                        double_sided: false,
                        base_color_texture: None,
                    });
                    (materials.len() - 1) as u32
                }),
            };
            let wp: Vec<Vec3> = prim.positions.iter().map(|&p| world.transform_point3(p)).collect();
            if let Some(v) = wp.iter().position(|p| !p.is_finite()) {
                return Err(src.err(format!(
                    "{} under {}: vertex {v} overflows to {} in world space",
                    mesh_label(root, mesh_i),
                    node_label(root, node),
                    wp[v]
                )));
            }
            let wn: Option<Vec<Vec3>> = prim
                .normals
                .as_ref()
                .map(|n| n.iter().map(|&n| (normal_matrix * n).normalize_or_zero()).collect());
            for &[a, b, c] in &prim.tris {
                let [a, b, c] = if flip { [a, c, b] } else { [a, b, c] };
                let p = [wp[a as usize], wp[b as usize], wp[c as usize]];
                if region.is_some() {
                    raw.push(p);
                }
                let cross = (p[1] - p[0]).cross(p[2] - p[0]);
                let longest = (p[1] - p[0])
                    .length_squared()
                    .max((p[2] - p[1]).length_squared())
                    .max((p[0] - p[2]).length_squared());
                let len = cross.length();
                if !(len > 1e-7 * longest) || !len.is_finite() {
                    degenerate[mesh_i] += 1;
                    continue;
                }
                let n = wn.as_ref().and_then(|wn| {
                    let n = [wn[a as usize], wn[b as usize], wn[c as usize]];
                    if n.contains(&Vec3::ZERO) { None } else { Some(n) }
                });
                let uv = prim
                    .uvs
                    .as_ref()
                    .map(|uv| [uv[a as usize], uv[b as usize], uv[c as usize]]);
                triangles.push(Triangle {
                    p,
                    n,
                    uv,
                    material,
                    interface: None,
                    mesh: mesh_i as u32,
                });
            }
        }
        if let Some(medium) = region {
            regions.push(RegionInstance {
                medium,
                mesh: mesh_i,
                node,
                tris: first..triangles.len(),
                raw,
            });
        }
    }
    for (m, &count) in degenerate.iter().enumerate() {
        if count > 0 {
            warnings.push(format!(
                "{f}: {}: skipped {count} degenerate (zero-area) triangle(s)",
                mesh_label(root, m)
            ));
        }
    }
    Ok(Geometry { triangles, regions })
}
