//! Media from the sidecar: validation, medium regions (closed meshes), nesting, density grids.
use super::TomlSrc;
use super::geometry::Geometry;
use super::names::{mesh_label, name_list, node_label};
use super::nodes::Traversal;
use super::sidecar::{DensityToml, Num, PerlinToml, Rgb3, Sidecar};
use crate::SceneError;
use crate::medium::{DensityGrid, Medium, parse_grid};
use crate::noise::PerlinDensity;
use crate::scene::MediumInterface;
use crate::vdb::{MAX_DENSE_VOXELS, read_vdb};
use glam::{DVec3, UVec3, Vec3};
use gltf::json;
use std::collections::HashMap;
use std::ops::Range;
use toml::Spanned;

enum GridSource {
    Values(Vec<f32>),
    Perlin(PerlinDensity),
}

struct GridPlan {
    /// What the density is, for messages ("the density grid 'x.bgrid'", "the perlin density").
    what: String,
    res: UVec3,
    source: GridSource,
    bounds: Option<(Vec3, Vec3)>,
}

pub(super) struct PlannedMedium {
    medium: Medium,
    mesh: Option<usize>,
    grid: Option<GridPlan>,
    region_span: Range<usize>,
}

pub(super) struct MediaPlan {
    media: Vec<PlannedMedium>,
    /// For each glTF mesh, the medium it bounds.
    pub region_of_mesh: Vec<Option<usize>>,
}

impl MediaPlan {
    pub fn empty(meshes: usize) -> Self {
        Self {
            media: Vec::new(),
            region_of_mesh: vec![None; meshes],
        }
    }
}

fn coefficient(t: &TomlSrc, what: &str, v: &Spanned<Rgb3>) -> Result<Vec3, SceneError> {
    let c = v.get_ref().0;
    if c.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(t.err_at(
            v.span(),
            format!("{what} = {c:?}: coefficients must be finite and non-negative"),
        ));
    }
    Ok(Vec3::from(c))
}

/// Checks the `[[media]]` tables and resolves their regions to glTF meshes.
pub(super) fn plan_media(
    t: &TomlSrc,
    sc: &Sidecar,
    root: &json::Root,
    trav: &Traversal,
) -> Result<MediaPlan, SceneError> {
    let mut plan = MediaPlan::empty(root.meshes.len());
    let mut global: Option<String> = None;
    for m in &sc.media {
        let name = m.name.get_ref().clone();
        let head = format!("[[media]] '{name}'");
        if name.is_empty() {
            return Err(t.err_at(m.name.span(), "[[media]]: name must not be empty"));
        }
        if plan.media.iter().any(|p| p.medium.name == name) {
            return Err(t.err_at(
                m.name.span(),
                format!("{head}: a medium of this name is already defined"),
            ));
        }
        let sigma_s = coefficient(t, &format!("{head}: sigma_s"), &m.sigma_s)?;
        let sigma_a = match &m.sigma_a {
            Some(v) => coefficient(t, &format!("{head}: sigma_a"), v)?,
            None => Vec3::ZERO,
        };
        let g = match &m.g {
            Some(g) => {
                let v = *g.get_ref();
                if !(v > -1.0 && v < 1.0) {
                    return Err(t.err_at(g.span(), format!("{head}: g = {v} must satisfy -1 < g < 1")));
                }
                v
            }
            None => 0.0,
        };
        let region = m.region.get_ref();
        let mesh = if region == "global" {
            if let Some(other) = &global {
                return Err(t.err_at(
                    m.region.span(),
                    format!("{head}: medium '{other}' is already global; at most one medium may be global"),
                ));
            }
            global = Some(name.clone());
            None
        } else {
            let by_mesh: Vec<usize> = (0..root.meshes.len())
                .filter(|&i| root.meshes[i].name.as_deref() == Some(region.as_str()))
                .collect();
            let mesh = match by_mesh.as_slice() {
                [one] => *one,
                [] => {
                    let by_node = root
                        .nodes
                        .iter()
                        .find(|n| n.name.as_deref() == Some(region.as_str()))
                        .and_then(|n| n.mesh);
                    match by_node {
                        Some(m) => m.value(),
                        None => {
                            let names = root.meshes.iter().filter_map(|m| m.name.as_deref());
                            let list = name_list(names, "meshes", "the glTF has no named meshes");
                            return Err(t.err_at(
                                m.region.span(),
                                format!("{head}: region '{region}' names no glTF mesh ({list}); use \"global\" or a mesh name"),
                            ));
                        }
                    }
                }
                _ => {
                    return Err(t.err_at(
                        m.region.span(),
                        format!(
                            "{head}: region '{region}' is ambiguous: {} glTF meshes have that name",
                            by_mesh.len()
                        ),
                    ));
                }
            };
            if !trav.instances.iter().any(|&(_, mi, _)| mi == mesh) {
                return Err(t.err_at(
                    m.region.span(),
                    format!(
                        "{head}: region {} is not used by any node of the scene",
                        mesh_label(root, mesh)
                    ),
                ));
            }
            if let Some(other) = plan.region_of_mesh[mesh] {
                return Err(t.err_at(
                    m.region.span(),
                    format!(
                        "{head}: {} already bounds medium '{}'; a mesh bounds at most one medium",
                        mesh_label(root, mesh),
                        plan.media[other].medium.name
                    ),
                ));
            }
            plan.region_of_mesh[mesh] = Some(plan.media.len());
            Some(mesh)
        };
        let grid = match &m.density {
            None => None,
            Some(d) => Some(plan_density(t, &head, d.span(), d.get_ref())?),
        };
        plan.media.push(PlannedMedium {
            medium: Medium {
                name,
                sigma_s,
                sigma_a,
                g,
                density: None,
            },
            mesh,
            grid,
            region_span: m.region.span(),
        });
    }
    Ok(plan)
}

fn density_bounds(t: &TomlSrc, head: &str, d: &DensityToml) -> Result<Option<(Vec3, Vec3)>, SceneError> {
    let Some(b) = &d.bounds else { return Ok(None) };
    let [lo, hi] = b.get_ref().map(Vec3::from);
    if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
        return Err(t.err_at(
            b.span(),
            format!(
                "{head}: density bounds {:?} must be finite with min < max on every axis",
                b.get_ref()
            ),
        ));
    }
    Ok(Some((lo, hi)))
}

/// Reads or checks one `density = {…}` table.
fn plan_density(t: &TomlSrc, head: &str, span: Range<usize>, d: &DensityToml) -> Result<GridPlan, SceneError> {
    let bounds = density_bounds(t, head, d)?;
    match (&d.grid, &d.perlin) {
        (Some(_), Some(p)) => Err(t.err_at(
            p.span(),
            format!("{head}: density has both 'grid' and 'perlin'; give one"),
        )),
        (None, None) => Err(t.err_at(
            span,
            format!("{head}: density needs 'grid = \"file\"' (.vdb or .bgrid) or 'perlin = {{ … }}'"),
        )),
        (None, Some(p)) => {
            if let Some(n) = &d.name {
                return Err(t.err_at(
                    n.span(),
                    format!("{head}: density 'name' selects a grid in a .vdb file; it does not apply to 'perlin'"),
                ));
            }
            let params = perlin_params(t, head, p.get_ref())?;
            let res = match &d.resolution {
                None => UVec3::splat(64),
                Some(r) => {
                    let v = r.get_ref().0;
                    let total = v.iter().map(|&x| x.max(0) as u128).product::<u128>();
                    if v.iter().any(|&x| !(1..=4096).contains(&x)) || total > MAX_DENSE_VOXELS as u128 {
                        return Err(t.err_at(
                            r.span(),
                            format!(
                                "{head}: density resolution {v:?} must be 1 to 4096 per axis and at most {MAX_DENSE_VOXELS} voxels in all (256^3)"
                            ),
                        ));
                    }
                    UVec3::new(v[0] as u32, v[1] as u32, v[2] as u32)
                }
            };
            Ok(GridPlan {
                what: "the perlin density".into(),
                res,
                source: GridSource::Perlin(params),
                bounds,
            })
        }
        (Some(g), None) => {
            if let Some(r) = &d.resolution {
                return Err(t.err_at(
                    r.span(),
                    format!("{head}: density 'resolution' applies only to 'perlin' (a grid file has its own)"),
                ));
            }
            let file = t.src.dir().join(g.get_ref());
            let is_vdb = file
                .extension()
                .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("vdb"));
            if let (Some(n), false) = (&d.name, is_vdb) {
                return Err(t.err_at(
                    n.span(),
                    format!(
                        "{head}: density 'name' selects a grid in a .vdb file; '{}' is not one",
                        g.get_ref()
                    ),
                ));
            }
            let bytes = std::fs::read(&file).map_err(|e| {
                t.err_at(
                    g.span(),
                    format!("{head}: density grid '{}' cannot be read: {e}", file.display()),
                )
            })?;
            let in_file = |e: String| {
                let (line, col) = super::sidecar::line_col(&t.text, g.span().start);
                SceneError::invalid(
                    &file,
                    format!(
                        "{e} (density grid of {head} in {}, line {line}, column {col})",
                        t.src.name()
                    ),
                )
            };
            let what = format!("the density grid '{}'", file.display());
            if is_vdb {
                let name = d.name.as_ref().map_or("density", |n| n.get_ref().as_str());
                let v = read_vdb(&bytes, name).map_err(in_file)?;
                let (lo, hi) = match bounds {
                    None => v.world_box(),
                    Some((lo, hi)) => v.box_for_bounds(lo.as_dvec3(), hi.as_dvec3()),
                };
                let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
                if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
                    return Err(in_file(format!(
                        "grid '{name}' maps to the empty or infinite world box {lo}..{hi}"
                    )));
                }
                Ok(GridPlan {
                    what,
                    res: v.res,
                    source: GridSource::Values(v.values),
                    bounds: Some((lo, hi)),
                })
            } else {
                let (res, values) = parse_grid(&bytes).map_err(in_file)?;
                Ok(GridPlan {
                    what,
                    res,
                    source: GridSource::Values(values),
                    bounds,
                })
            }
        }
    }
}

/// Checks the `perlin = {…}` keys; missing ones take [`PerlinDensity::default`]'s values.
fn perlin_params(t: &TomlSrc, head: &str, p: &PerlinToml) -> Result<PerlinDensity, SceneError> {
    let def = PerlinDensity::default();
    let num = |key: &str, v: &Option<toml::Spanned<Num>>, default: f32, ok: &dyn Fn(f64) -> bool, rule: &str| match v {
        None => Ok(default),
        Some(v) => {
            let x = v.get_ref().0;
            if x.is_finite() && ok(x) && (x as f32).is_finite() {
                Ok(x as f32)
            } else {
                Err(t.err_at(v.span(), format!("{head}: density.perlin.{key} = {x} must be {rule}")))
            }
        }
    };
    let octaves = match &p.octaves {
        None => def.octaves,
        Some(o) => {
            let v = *o.get_ref();
            if !(1..=16).contains(&v) {
                return Err(t.err_at(
                    o.span(),
                    format!("{head}: density.perlin.octaves = {v} must be between 1 and 16"),
                ));
            }
            v as u32
        }
    };
    let seed = match &p.seed {
        None => def.seed,
        Some(s) => {
            let v = *s.get_ref();
            u32::try_from(v).map_err(|_| {
                t.err_at(
                    s.span(),
                    format!("{head}: density.perlin.seed = {v} must be between 0 and 4294967295"),
                )
            })?
        }
    };
    Ok(PerlinDensity {
        scale: num(
            "scale",
            &p.scale,
            def.scale,
            &|x| x > 0.0 && x <= 1e4,
            "finite, > 0 and <= 10000",
        )?,
        octaves,
        gain: num(
            "gain",
            &p.gain,
            def.gain,
            &|x| (0.0..=4.0).contains(&x),
            "between 0 and 4",
        )?,
        lacunarity: num(
            "lacunarity",
            &p.lacunarity,
            def.lacunarity,
            &|x| x > 0.0 && x <= 16.0,
            "> 0 and <= 16",
        )?,
        height_falloff: num(
            "height_falloff",
            &p.height_falloff,
            def.height_falloff,
            &|x| x.abs() <= 50.0,
            "finite, between -50 and 50",
        )?,
        bias: num("bias", &p.bias, def.bias, &|x| x.abs() <= 1e6, "finite (|bias| <= 1e6)")?,
        amplitude: num(
            "amplitude",
            &p.amplitude,
            def.amplitude,
            &|x| x.abs() <= 1e6,
            "finite (|amplitude| <= 1e6)",
        )?,
        seed,
    })
}

/// Checks that an instance is a closed, consistently oriented manifold; `Err` says why not.
fn check_closed(raw: &[[Vec3; 3]]) -> Result<(), String> {
    let key = |p: Vec3| p.to_array().map(|c| if c == 0.0 { 0u32 } else { c.to_bits() });
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut pos: Vec<Vec3> = Vec::new();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    let mut faces = 0usize;
    for tri in raw {
        let v = tri.map(|p| {
            *ids.entry(key(p)).or_insert_with(|| {
                pos.push(p);
                (pos.len() - 1) as u32
            })
        });
        if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
            continue; // collapsed triangle: no edges
        }
        faces += 1;
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    if faces == 0 {
        return Err("it has no triangles".into());
    }
    let fmt = |a: u32, b: u32| {
        let (p, q) = (pos[a as usize], pos[b as usize]);
        format!("({}, {}, {})-({}, {}, {})", p.x, p.y, p.z, q.x, q.y, q.z)
    };
    let mut open = 0usize;
    let mut example_open = None;
    // Deterministic order for the example edge.
    let mut sorted: Vec<(&(u32, u32), &u32)> = edges.iter().collect();
    sorted.sort_unstable();
    for &(&(a, b), &n) in &sorted {
        let back = edges.get(&(b, a)).copied().unwrap_or(0);
        if n > 1 {
            return Err(if back + n > 2 {
                format!(
                    "the edge {} is shared by {} triangles (not a manifold)",
                    fmt(a, b),
                    n + back
                )
            } else {
                format!(
                    "the triangles are not consistently oriented (two triangles traverse the edge {} in the same direction)",
                    fmt(a, b)
                )
            });
        }
        if back == 0 {
            open += 1;
            example_open.get_or_insert((a, b));
        } else if back > 1 {
            return Err(format!(
                "the edge {} is shared by {} triangles (not a manifold)",
                fmt(a, b),
                n + back
            ));
        }
    }
    if let Some((a, b)) = example_open {
        return Err(format!(
            "it has {open} open edge(s) that belong to only one triangle, e.g. {} (vertices are welded by exact position)",
            fmt(a, b)
        ));
    }
    Ok(())
}

/// Signed volume (positive when the triangles face outward).
fn signed_volume(raw: &[[Vec3; 3]]) -> f64 {
    let Some(first) = raw.first() else { return 0.0 };
    let o = first[0].as_dvec3();
    raw.iter()
        .map(|t| {
            let [a, b, c] = t.map(|p| p.as_dvec3() - o);
            a.dot(b.cross(c))
        })
        .sum::<f64>()
        / 6.0
}

/// Distance along `d` to the triangle, if the ray from `o` hits it (Möller–Trumbore, t > 0).
fn ray_triangle(o: DVec3, d: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0).then_some(t)
}

/// True when `p` is inside the closed triangle set (odd number of crossings along a fixed ray).
fn inside(p: Vec3, raw: &[[Vec3; 3]]) -> bool {
    let d = DVec3::new(0.5773, 0.6168, -0.5351).normalize();
    let o = p.as_dvec3();
    raw.iter()
        .filter(|t| {
            let [a, b, c] = t.map(|v| v.as_dvec3());
            ray_triangle(o, d, a, b, c).is_some()
        })
        .count()
        % 2
        == 1
}

fn bounds_of<'a>(points: impl Iterator<Item = &'a Vec3>) -> Option<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo.x <= hi.x).then_some((lo, hi))
}

/// Checks region meshes, orients them outward, assigns medium interfaces and builds density grids.
pub(super) fn finish_media(
    t: Option<&TomlSrc>,
    root: &json::Root,
    plan: MediaPlan,
    geo: &mut Geometry,
    warnings: &mut Vec<String>,
) -> Result<(Vec<Medium>, Option<u32>), SceneError> {
    let Some(t) = t else {
        return Ok((Vec::new(), None));
    };
    let global = plan.media.iter().position(|m| m.mesh.is_none()).map(|i| i as u32);
    let mut volumes = Vec::with_capacity(geo.regions.len());
    for r in geo.regions.iter_mut() {
        let pm = &plan.media[r.medium];
        let head = format!("[[media]] '{}'", pm.medium.name);
        let what = if root.meshes[r.mesh].name.is_some() && root.nodes[r.node].name == root.meshes[r.mesh].name {
            mesh_label(root, r.mesh)
        } else {
            format!(
                "{} (instanced by {})",
                mesh_label(root, r.mesh),
                node_label(root, r.node)
            )
        };
        if let Err(why) = check_closed(&r.raw) {
            return Err(t.err_at(
                pm.region_span.clone(),
                format!("{head}: region {what} must be a closed mesh, but {why}"),
            ));
        }
        let v = signed_volume(&r.raw);
        let (lo, hi) = bounds_of(r.raw.iter().flatten()).expect("closed mesh has triangles");
        let extent = (hi - lo).as_dvec3();
        if !(v.abs() > 1e-9 * extent.x.max(extent.y).max(extent.z).powi(3)) {
            return Err(t.err_at(
                pm.region_span.clone(),
                format!("{head}: region {what} encloses no volume"),
            ));
        }
        if v < 0.0 {
            warnings.push(format!(
                "{}: {head}: the triangles of region {what} face inward; they were flipped so their normals point out of the medium",
                t.src.name()
            ));
            for tri in &mut geo.triangles[r.tris.clone()] {
                tri.p.swap(1, 2);
                if let Some(n) = &mut tri.n {
                    n.swap(1, 2);
                    *n = n.map(|v| -v);
                }
            }
            for tri in &mut r.raw {
                tri.swap(1, 2);
            }
        }
        volumes.push(v.abs());
    }
    // Nesting: the innermost other region instance containing a point of this one.
    let n = geo.regions.len();
    let mut outside = vec![global; n];
    for (r, out) in geo.regions.iter().zip(outside.iter_mut()) {
        let probe = match geo.triangles.get(r.tris.clone()).and_then(|ts| ts.first()) {
            Some(tri) => (tri.p[0] + tri.p[1] + tri.p[2]) / 3.0,
            None => continue,
        };
        let mut best: Option<(f64, usize)> = None;
        for (s, &volume) in geo.regions.iter().zip(&volumes) {
            if s.mesh == r.mesh || !inside(probe, &s.raw) {
                continue;
            }
            if best.is_none_or(|(v, _)| volume < v) {
                best = Some((volume, s.medium));
            }
        }
        if let Some((_, medium)) = best {
            *out = Some(medium as u32);
        }
    }
    for (i, r) in geo.regions.iter().enumerate() {
        let iface = MediumInterface {
            inside: Some(r.medium as u32),
            outside: outside[i],
        };
        for tri in &mut geo.triangles[r.tris.clone()] {
            tri.interface = Some(iface);
        }
    }
    // Density grids.
    let mut media = Vec::with_capacity(plan.media.len());
    for (mi, pm) in plan.media.into_iter().enumerate() {
        let mut medium = pm.medium;
        if let Some(g) = pm.grid {
            let bounds = match g.bounds {
                Some(b) => Some(b),
                None if pm.mesh.is_some() => bounds_of(
                    geo.regions
                        .iter()
                        .filter(|r| r.medium == mi)
                        .flat_map(|r| r.raw.iter().flatten()),
                ),
                None => bounds_of(geo.triangles.iter().flat_map(|t| t.p.iter())),
            };
            let Some((lo, hi)) = bounds.filter(|(lo, hi)| lo.cmplt(*hi).all()) else {
                return Err(t.err_at(
                    pm.region_span.clone(),
                    format!(
                        "[[media]] '{}': {} needs 'bounds' (the default box is empty or flat)",
                        medium.name, g.what
                    ),
                ));
            };
            medium.density = Some(match g.source {
                GridSource::Values(values) => DensityGrid::new(g.res, lo, hi, values),
                GridSource::Perlin(p) => p.bake(g.res, lo, hi),
            });
        }
        media.push(medium);
    }
    Ok((media, global))
}
