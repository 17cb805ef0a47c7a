//! `beamlight export-mitsuba SCENE.toml OUT.xml`: the same scene for Mitsuba 3 (scene format
//! 3.0.0), for side-by-side comparisons (`cargo xtask bench`).
//!
//! What is written, and how our conventions map onto Mitsuba's:
//! * **Meshes**: one binary little-endian PLY per (glTF mesh, material, medium interface), in
//!   `OUT_meshes/` beside the XML, triangles unindexed in world space (our loader has already
//!   applied the node transforms). Vertex normals are written when the glTF had them, except
//!   for emitters, whose emitting side must follow the winding as ours does.
//! * **Materials**: our BSDFs are two-sided, Mitsuba's `diffuse` is not, so every opaque BSDF
//!   is wrapped in `twosided`. Lambert → `diffuse` (exact); mirror → `conductor` with
//!   `material="none"` scaled by the reflectance (exact); glass → `dielectric` with our
//!   relative IOR and tint (exact for clear glass); invisible medium boundaries → `null`.
//!   Modified Phong has no Mitsuba 3 counterpart: it becomes a `blendbsdf` of `diffuse` and a
//!   Beckmann `roughconductor` (α = √(2/(n+2)), the usual Phong↔Beckmann match), which is
//!   **not** the same BRDF (reported). Base-colour textures are not exported (the flat factor
//!   is; reported).
//! * **Emitters**: emissive materials → `area` emitters, which in Mitsuba emit from the front
//!   face (counter-clockwise winding) only, like ours; double-sided emission cannot be
//!   expressed on one shape and is exported one-sided (reported). Point lights → `point`
//!   (intensity = our radiant intensity), spot lights → `spot` (cone angles kept, Mitsuba's
//!   falloff curve differs: reported), directional → `directional`.
//! * **Media**: homogeneous → `homogeneous` (σt and albedo σs/σt in RGB, HG phase `g`);
//!   density grids → `heterogeneous` with a `gridvolume` read from a `.vol` file (values at
//!   voxel centres, as ours; the grid's box by `to_world`) and `scale` = σt (grey σt only;
//!   a chromatic σt uses its mean, reported). Mitsuba attaches media to shapes: a shape gets
//!   the medium on each side as `interior`/`exterior` — the region's medium inside a region
//!   mesh, and the global medium everywhere else (our global medium fills all space outside
//!   regions, so both sides of an ordinary wall are in it) — and the sensor gets the medium
//!   the camera sits in.
//! * **Camera**: `perspective` with `fov_axis="y"` (glTF's `yfov` is vertical) and a
//!   `lookat` from our camera frame (glTF looks down −Z, Mitsuba's camera down +Z: `lookat`
//!   sidesteps the handedness), a tiny `near_clip` (Mitsuba starts camera rays at the near
//!   plane, which matters inside a medium), `hdrfilm` at the scene's resolution with a `box`
//!   reconstruction filter (our pixel value is the plain average over the pixel).
//! * **Integrator**: `volpath` (unbounded depth, Russian roulette from depth 5).
use anyhow::{Context, Result};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf, light::PunctualLight, medium::Medium};
use glam::Vec3;
use std::{
    collections::BTreeMap,
    fmt::Write as _,
    path::{Path, PathBuf},
};

/// What an export wrote and what it could not express exactly.
#[derive(Debug, Default)]
pub struct ExportReport {
    pub shapes: usize,
    pub area_emitters: usize,
    pub punctual_emitters: usize,
    pub media: usize,
    pub triangles: usize,
    /// One line per thing that was approximated or left out.
    pub not_exported: Vec<String>,
}

fn rgb(c: Rgb) -> String {
    format!("{:.7}, {:.7}, {:.7}", c.x, c.y, c.z)
}

fn v3(p: Vec3) -> String {
    format!("{:.7}, {:.7}, {:.7}", p.x, p.y, p.z)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// File-name-safe version of a glTF name.
fn file_safe(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' })
        .collect()
}

/// A binary little-endian PLY of unindexed triangles (optionally with vertex normals).
pub fn ply_bytes(triangles: &[([Vec3; 3], Option<[Vec3; 3]>)], flip: bool) -> Vec<u8> {
    let normals = triangles.iter().all(|(_, n)| n.is_some()) && !triangles.is_empty();
    let mut out = Vec::new();
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment beamlight export-mitsuba\n");
    let _ = writeln!(header, "element vertex {}", 3 * triangles.len());
    header.push_str("property float x\nproperty float y\nproperty float z\n");
    if normals {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    let _ = writeln!(header, "element face {}", triangles.len());
    header.push_str("property list uchar int vertex_indices\nend_header\n");
    out.extend_from_slice(header.as_bytes());
    for (p, n) in triangles {
        for k in 0..3 {
            for c in p[k].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if normals {
                let nk = n.expect("checked")[k];
                for c in nk.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
    }
    for i in 0..triangles.len() as i32 {
        out.push(3);
        let idx = if flip {
            [3 * i, 3 * i + 2, 3 * i + 1]
        } else {
            [3 * i, 3 * i + 1, 3 * i + 2]
        };
        for v in idx {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Mitsuba's `.vol` grid format: "VOL", version 3, encoding 1 (float32), resolution,
/// channels, bounding box, then the values with x fastest, then y, then z (the same order as
/// our grids).
pub fn vol_bytes(res: [u32; 3], lo: Vec3, hi: Vec3, values: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + 4 * values.len());
    out.extend_from_slice(b"VOL");
    out.push(3);
    out.extend_from_slice(&1i32.to_le_bytes());
    for r in res {
        out.extend_from_slice(&(r as i32).to_le_bytes());
    }
    out.extend_from_slice(&1i32.to_le_bytes());
    for c in lo.to_array().into_iter().chain(hi.to_array()) {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

fn medium_xml(i: usize, m: &Medium, dir_name: &str, out_dir: &Path, report: &mut ExportReport) -> Result<String> {
    let st = m.sigma_t();
    let albedo = Rgb::new(
        if st.x > 0.0 { m.sigma_s.x / st.x } else { 0.0 },
        if st.y > 0.0 { m.sigma_s.y / st.y } else { 0.0 },
        if st.z > 0.0 { m.sigma_s.z / st.z } else { 0.0 },
    );
    let phase = format!(
        "        <phase type=\"hg\">\n            <float name=\"g\" value=\"{}\"/>\n        </phase>\n",
        m.g
    );
    let id = format!("medium{i}");
    let mut s = String::new();
    match &m.density {
        None => {
            let _ = writeln!(s, "    <medium type=\"homogeneous\" id=\"{id}\">");
            let _ = writeln!(s, "        <rgb name=\"albedo\" value=\"{}\"/>", rgb(albedo));
            let _ = writeln!(s, "        <rgb name=\"sigma_t\" value=\"{}\"/>", rgb(st));
            s.push_str(&phase);
        }
        Some(g) => {
            let grey = st.max_element() - st.min_element() <= 1e-6 * st.max_element();
            let scale = if grey { st.x } else { (st.x + st.y + st.z) / 3.0 };
            if !grey {
                report.not_exported.push(format!(
                    "medium '{}': chromatic sigma_t {:?} of a density grid exported as its mean {scale} (Mitsuba's grid here is one channel)",
                    m.name, st
                ));
            }
            let file = format!("{dir_name}/{}.vol", file_safe(&m.name));
            std::fs::write(
                out_dir.join(&file),
                vol_bytes([g.res.x, g.res.y, g.res.z], g.lo, g.hi, &g.values),
            )
            .with_context(|| format!("writing {file}"))?;
            let size = g.hi - g.lo;
            let _ = writeln!(s, "    <medium type=\"heterogeneous\" id=\"{id}\">");
            let _ = writeln!(s, "        <volume name=\"sigma_t\" type=\"gridvolume\">");
            let _ = writeln!(
                s,
                "            <string name=\"filename\" value=\"{}\"/>",
                xml_escape(&file)
            );
            let _ = writeln!(s, "            <transform name=\"to_world\">");
            let _ = writeln!(s, "                <scale value=\"{}\"/>", v3(size));
            let _ = writeln!(s, "                <translate value=\"{}\"/>", v3(g.lo));
            let _ = writeln!(s, "            </transform>");
            let _ = writeln!(s, "        </volume>");
            let _ = writeln!(s, "        <rgb name=\"albedo\" value=\"{}\"/>", rgb(albedo));
            let _ = writeln!(s, "        <float name=\"scale\" value=\"{scale}\"/>");
            s.push_str(&phase);
        }
    }
    let _ = writeln!(s, "    </medium>");
    Ok(s)
}

fn bsdf_xml(bsdf: &Option<Bsdf>, name: &str, textured: bool, report: &mut ExportReport) -> String {
    if textured {
        report.not_exported.push(format!(
            "material '{name}': base-colour texture (the flat base colour factor is exported)"
        ));
    }
    let twosided = |inner: String| format!("        <bsdf type=\"twosided\">\n{inner}        </bsdf>\n");
    match bsdf {
        None => "        <bsdf type=\"null\"/>\n".to_string(),
        Some(Bsdf::Lambert { albedo }) => twosided(format!(
            "            <bsdf type=\"diffuse\">\n                <rgb name=\"reflectance\" value=\"{}\"/>\n            </bsdf>\n",
            rgb(*albedo)
        )),
        Some(Bsdf::Mirror { reflectance }) => twosided(format!(
            "            <bsdf type=\"conductor\">\n                <string name=\"material\" value=\"none\"/>\n                <rgb name=\"specular_reflectance\" value=\"{}\"/>\n            </bsdf>\n",
            rgb(*reflectance)
        )),
        Some(Bsdf::Glass { ior, tint }) => format!(
            "        <bsdf type=\"dielectric\">\n            <float name=\"int_ior\" value=\"{ior}\"/>\n            <float name=\"ext_ior\" value=\"1\"/>\n            <rgb name=\"specular_reflectance\" value=\"{t}\"/>\n            <rgb name=\"specular_transmittance\" value=\"{t}\"/>\n        </bsdf>\n",
            t = rgb(*tint)
        ),
        Some(Bsdf::Phong {
            diffuse,
            specular,
            exponent,
        }) => {
            report.not_exported.push(format!(
                "material '{name}': modified Phong (exponent {exponent}) has no Mitsuba 3 counterpart; exported as a blend of diffuse and a Beckmann rough conductor (alpha = sqrt(2/(n+2))), a different BRDF"
            ));
            let (kd, ks) = (diffuse.max_element(), specular.max_element());
            let w = if kd + ks > 0.0 { ks / (kd + ks) } else { 0.0 };
            let d = if w < 1.0 { *diffuse / (1.0 - w) } else { Rgb::ZERO };
            let s = if w > 0.0 { *specular / w } else { Rgb::ZERO };
            let alpha = (2.0 / (exponent + 2.0)).sqrt();
            twosided(format!(
                "            <bsdf type=\"blendbsdf\">\n                <float name=\"weight\" value=\"{w}\"/>\n                <bsdf type=\"diffuse\">\n                    <rgb name=\"reflectance\" value=\"{}\"/>\n                </bsdf>\n                <bsdf type=\"roughconductor\">\n                    <string name=\"distribution\" value=\"beckmann\"/>\n                    <string name=\"material\" value=\"none\"/>\n                    <float name=\"alpha\" value=\"{alpha}\"/>\n                    <rgb name=\"specular_reflectance\" value=\"{}\"/>\n                </bsdf>\n            </bsdf>\n",
                rgb(d),
                rgb(s)
            ))
        }
    }
}

/// Writes `scene` as Mitsuba 3 XML to `xml_path`, its meshes and grids into `<stem>_meshes/`
/// beside it. `camera_medium` is the medium the camera sits in (see `TraceScene`).
pub fn export(scene: &Scene, camera_medium: Option<u32>, xml_path: &Path) -> Result<ExportReport> {
    let mut report = ExportReport::default();
    let out_dir = match xml_path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let stem = xml_path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "scene".into());
    let dir_name = format!("{}_meshes", file_safe(&stem));
    std::fs::create_dir_all(out_dir.join(&dir_name))
        .with_context(|| format!("creating {}", out_dir.join(&dir_name).display()))?;

    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    let _ = writeln!(
        xml,
        "<!-- Written by `beamlight export-mitsuba` from {} -->",
        xml_escape(&scene.source.display().to_string())
    );
    xml.push_str("<scene version=\"3.0.0\">\n");
    xml.push_str(
        "    <integrator type=\"volpath\">\n        <integer name=\"max_depth\" value=\"-1\"/>\n    </integrator>\n",
    );

    for (i, m) in scene.media.iter().enumerate() {
        xml.push_str(&medium_xml(i, m, &dir_name, &out_dir, &mut report)?);
        report.media += 1;
    }
    let medium_ref = |name: &str, m: Option<u32>| {
        m.map(|i| format!("        <ref name=\"{name}\" id=\"medium{i}\"/>\n"))
            .unwrap_or_default()
    };

    // Camera.
    let cam = &scene.camera;
    let (lo, hi) = scene.bounds();
    let diag = (hi - lo).length().max(1e-6);
    let origin = cam.position();
    let target = origin + cam.forward();
    let up = cam.to_world.transform_vector3(Vec3::Y).normalize();
    xml.push_str("    <sensor type=\"perspective\">\n");
    xml.push_str("        <string name=\"fov_axis\" value=\"y\"/>\n");
    let _ = writeln!(xml, "        <float name=\"fov\" value=\"{}\"/>", cam.yfov.to_degrees());
    let _ = writeln!(xml, "        <float name=\"near_clip\" value=\"{}\"/>", 1e-5 * diag);
    let _ = writeln!(xml, "        <float name=\"far_clip\" value=\"{}\"/>", 1e4 * diag);
    let _ = writeln!(
        xml,
        "        <transform name=\"to_world\">\n            <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n        </transform>",
        v3(origin),
        v3(target),
        v3(up)
    );
    xml.push_str(&medium_ref("medium", camera_medium));
    xml.push_str("        <sampler type=\"independent\">\n            <integer name=\"sample_count\" value=\"16\"/>\n        </sampler>\n");
    let _ = writeln!(
        xml,
        "        <film type=\"hdrfilm\">\n            <integer name=\"width\" value=\"{}\"/>\n            <integer name=\"height\" value=\"{}\"/>\n            <string name=\"pixel_format\" value=\"rgb\"/>\n            <string name=\"component_format\" value=\"float32\"/>\n            <rfilter type=\"box\"/>\n        </film>",
        scene.render.width, scene.render.height
    );
    xml.push_str("    </sensor>\n");

    // Shapes: one per (mesh, material, interface).
    type Key = (u32, u32, Option<(Option<u32>, Option<u32>)>);
    type Tri = ([Vec3; 3], Option<[Vec3; 3]>);
    let mut groups: BTreeMap<Key, Vec<Tri>> = BTreeMap::new();
    for t in &scene.triangles {
        let iface = t.interface.map(|f| (f.inside, f.outside));
        groups.entry((t.mesh, t.material, iface)).or_default().push((t.p, t.n));
    }
    let mut double_sided_reported = std::collections::BTreeSet::new();
    let mut textured_reported = std::collections::BTreeSet::new();
    for ((mesh, material, iface), mut tris) in groups {
        let m = &scene.materials[material as usize];
        let emissive = m.is_emissive();
        if emissive {
            for t in &mut tris {
                t.1 = None;
            }
        }
        let file = format!(
            "{dir_name}/{:03}_{}_{}.ply",
            report.shapes,
            file_safe(&scene.meshes[mesh as usize]),
            file_safe(&m.name)
        );
        std::fs::write(out_dir.join(&file), ply_bytes(&tris, false)).with_context(|| format!("writing {file}"))?;
        report.shapes += 1;
        report.triangles += tris.len();
        let _ = writeln!(
            xml,
            "    <shape type=\"ply\" id=\"shape{}\">\n        <string name=\"filename\" value=\"{}\"/>",
            report.shapes - 1,
            xml_escape(&file)
        );
        if tris.iter().all(|t| t.1.is_none()) {
            xml.push_str("        <boolean name=\"face_normals\" value=\"true\"/>\n");
        }
        let textured = m.base_color_texture.is_some() && textured_reported.insert(material);
        xml.push_str(&bsdf_xml(&m.bsdf, &m.name, textured, &mut report));
        if emissive {
            if m.double_sided && double_sided_reported.insert(material) {
                report.not_exported.push(format!(
                    "material '{}': double-sided emission (exported one-sided, from the front face)",
                    m.name
                ));
            }
            let _ = writeln!(
                xml,
                "        <emitter type=\"area\">\n            <rgb name=\"radiance\" value=\"{}\"/>\n        </emitter>",
                rgb(m.emission)
            );
            report.area_emitters += 1;
        }
        let (interior, exterior) = match iface {
            Some((inside, outside)) => (inside, outside),
            None => (scene.global_medium, scene.global_medium),
        };
        xml.push_str(&medium_ref("interior", interior));
        xml.push_str(&medium_ref("exterior", exterior));
        xml.push_str("    </shape>\n");
    }

    for l in &scene.lights {
        match l {
            PunctualLight::Point { position, intensity } => {
                let _ = writeln!(
                    xml,
                    "    <emitter type=\"point\">\n        <point name=\"position\" value=\"{}\"/>\n        <rgb name=\"intensity\" value=\"{}\"/>\n{}    </emitter>",
                    v3(*position),
                    rgb(*intensity),
                    medium_ref("medium", scene.global_medium)
                );
            }
            PunctualLight::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
            } => {
                report
                    .not_exported
                    .push("spot light: the glTF falloff between the cones (Mitsuba's spot uses its own curve)".into());
                let up = if direction.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
                let _ = writeln!(
                    xml,
                    "    <emitter type=\"spot\">\n        <transform name=\"to_world\">\n            <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n        </transform>\n        <rgb name=\"intensity\" value=\"{}\"/>\n        <float name=\"cutoff_angle\" value=\"{}\"/>\n        <float name=\"beam_width\" value=\"{}\"/>\n{}    </emitter>",
                    v3(*position),
                    v3(*position + *direction),
                    v3(up),
                    rgb(*intensity),
                    cos_outer.clamp(-1.0, 1.0).acos().to_degrees(),
                    cos_inner.clamp(-1.0, 1.0).acos().to_degrees(),
                    medium_ref("medium", scene.global_medium)
                );
            }
            PunctualLight::Directional { direction, irradiance } => {
                let _ = writeln!(
                    xml,
                    "    <emitter type=\"directional\">\n        <vector name=\"direction\" value=\"{}\"/>\n        <rgb name=\"irradiance\" value=\"{}\"/>\n    </emitter>",
                    v3(*direction),
                    rgb(*irradiance)
                );
            }
        }
        report.punctual_emitters += 1;
    }
    xml.push_str("</scene>\n");
    let mut seen = std::collections::BTreeSet::new();
    report.not_exported.retain(|w| seen.insert(w.clone()));
    std::fs::write(xml_path, xml).with_context(|| format!("writing {}", xml_path.display()))?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use beamlight_scene::load::load_scene;

    fn scene_path(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../assets/scenes")
            .join(name)
    }

    /// PLY header counts and the size of the binary body.
    fn ply_counts(bytes: &[u8]) -> (usize, usize, bool, usize) {
        let end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .expect("a PLY header")
            + 11;
        let header = std::str::from_utf8(&bytes[..end]).unwrap();
        let count = |e: &str| {
            header
                .lines()
                .find_map(|l| l.strip_prefix(&format!("element {e} ")))
                .unwrap()
                .parse::<usize>()
                .unwrap()
        };
        (
            count("vertex"),
            count("face"),
            header.contains("property float nx"),
            bytes.len() - end,
        )
    }

    #[test]
    fn export_parses_with_the_right_counts() {
        for (name, media, phong) in [
            ("cornell_fog.toml", 1, true),
            ("cornell.toml", 0, false),
            ("cornell_smoke.toml", 1, false),
        ] {
            let scene = load_scene(&scene_path(name)).unwrap();
            let dir = tempfile::tempdir().unwrap();
            let xml_path = dir.path().join("scene.xml");
            let report = export(&scene, scene.global_medium, &xml_path).unwrap();
            let text = std::fs::read_to_string(&xml_path).unwrap();
            let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
            let root = doc.root_element();
            assert_eq!(root.tag_name().name(), "scene");
            assert_eq!(root.attribute("version"), Some("3.0.0"));
            let children = |tag: &str| root.children().filter(|n| n.has_tag_name(tag)).count();
            let shapes: Vec<_> = root.children().filter(|n| n.has_tag_name("shape")).collect();
            assert_eq!(shapes.len(), report.shapes);
            assert_eq!(children("medium"), media);
            assert_eq!(report.media, media);
            assert_eq!(children("sensor"), 1);
            // The Cornell box has one emitter: the light quad.
            let area = doc
                .descendants()
                .filter(|n| n.has_tag_name("emitter") && n.attribute("type") == Some("area"))
                .count();
            assert_eq!(area, 1);
            assert_eq!(report.area_emitters, 1);
            // Every shape sits in the global medium on both sides (there are no regions).
            for s in &shapes {
                let refs = s.children().filter(|n| n.has_tag_name("ref")).count();
                assert_eq!(refs, 2 * media, "{name}");
            }
            // The PLYs hold every triangle, three unindexed vertices each.
            let mut triangles = 0;
            for s in &shapes {
                let file = s
                    .children()
                    .find(|n| n.has_tag_name("string") && n.attribute("name") == Some("filename"))
                    .and_then(|n| n.attribute("value"))
                    .unwrap();
                let bytes = std::fs::read(dir.path().join(file)).unwrap();
                let (v, f, normals, body) = ply_counts(&bytes);
                assert_eq!(v, 3 * f);
                assert_eq!(body, v * if normals { 24 } else { 12 } + f * 13);
                triangles += f;
            }
            assert_eq!(triangles, scene.triangles.len());
            assert_eq!(
                report.not_exported.iter().any(|w| w.contains("Phong")),
                phong,
                "{:?}",
                report.not_exported
            );
            let fov = doc
                .descendants()
                .find(|n| n.attribute("name") == Some("fov_axis"))
                .and_then(|n| n.attribute("value"));
            assert_eq!(fov, Some("y"));
            if name == "cornell_smoke.toml" {
                let vol = std::fs::read(dir.path().join("scene_meshes/smoke.vol")).unwrap();
                let g = scene.media[0].density.as_ref().unwrap();
                assert_eq!(&vol[..4], b"VOL\x03");
                assert_eq!(vol.len(), 48 + 4 * g.values.len());
            }
        }
    }

    #[test]
    fn flipped_ply_reverses_the_winding() {
        let tri = [([Vec3::ZERO, Vec3::X, Vec3::Y], None)];
        let a = ply_bytes(&tri, false);
        let b = ply_bytes(&tri, true);
        let n = a.len();
        assert_eq!(&a[n - 12..], &[0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
        assert_eq!(&b[n - 12..], &[0, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0]);
    }
}
