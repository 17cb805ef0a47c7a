//! Assembling the [`Scene`]: node traversal, materials (+ overrides), triangles, camera, lights,
//! render settings.
use super::gltf_read::{self, GltfDoc};
use super::images::TextureLoader;
use super::media::{self, MediaPlan, RegionInstance};
use super::sidecar::{MaterialToml, Rgb3, Sidecar};
use super::{Src, TomlSrc};
use crate::bsdf::{Bsdf, Material};
use crate::camera::Camera;
use crate::light::PunctualLight;
use crate::scene::{RenderSettings, Triangle};
use crate::{Rgb, Scene, SceneError};
use glam::{Mat3, Mat4, Quat, Vec2, Vec3};
use gltf::json::{self, mesh::Mode, mesh::Semantic, validation::Checked};
use std::path::Path;
use toml::Spanned;

/// Largest accepted image side.
pub(super) const MAX_RESOLUTION: u32 = 16384;
/// Image height when the sidecar does not give one.
pub(super) const DEFAULT_HEIGHT: u32 = 512;
/// Albedo of the material given to primitives without one: the glTF default material has
/// baseColorFactor 1, which maps to a white Lambert surface.
const DEFAULT_ALBEDO: f32 = 1.0;
/// Vertical field of view of the camera made up when the glTF has none.
const DEFAULT_YFOV_DEGREES: f32 = 40.0;

pub(super) fn build_scene(
    src: Src,
    bytes: &[u8],
    toml: Option<(&TomlSrc, &Sidecar)>,
    source: &Path,
) -> Result<Scene, SceneError> {
    let mut warnings = Vec::new();
    let doc = gltf_read::read_gltf(&src, bytes, &mut warnings)?;
    let root = &doc.root;
    feature_warnings(&src, root, &mut warnings);
    let trav = traverse(&src, root, &mut warnings)?;
    let (mut materials, mut base_tex) = convert_materials(&src, root, &mut warnings)?;
    let mut loader = TextureLoader::new(&src, &doc);
    if let Some((t, sc)) = toml {
        apply_overrides(t, sc, root, &mut materials, &mut base_tex, &mut loader, &mut warnings)?;
    }
    let tex_coord = attach_textures(&src, root, &mut materials, &base_tex, &mut loader, &mut warnings)?;
    let textures = loader.textures;
    let plan = match toml {
        Some((t, sc)) => media::plan_media(t, sc, root, &trav)?,
        None => MediaPlan::empty(root.meshes.len()),
    };
    let mut geo = build_triangles(&src, &doc, &trav, &plan, &mut materials, &tex_coord, &mut warnings)?;
    let (media, global_medium) = media::finish_media(toml.map(|(t, _)| t), root, plan, &mut geo, &mut warnings)?;

    let mut lights = Vec::new();
    for &(node, light, world) in &trav.lights {
        lights.push(convert_light(&src, root, node, light, world, &mut warnings)?);
    }
    let (camera, aspect) = choose_camera(&src, root, &trav, toml, &geo.triangles, &lights, &mut warnings)?;
    let render = render_settings(toml, aspect)?;

    let meshes = root.meshes.iter().enumerate().map(|(i, m)| mesh_name(m, i)).collect();
    Ok(Scene {
        source: source.to_path_buf(),
        triangles: geo.triangles,
        meshes,
        materials,
        textures,
        media,
        global_medium,
        lights,
        camera,
        render,
        warnings,
    })
}

/// "`label`: 'a', 'b'" (sorted, without repeats), or `none` when there are no names: the list
/// of valid choices an error message offers.
pub(super) fn name_list<'a>(names: impl Iterator<Item = &'a str>, label: &str, none: &str) -> String {
    let mut names: Vec<String> = names.map(|n| format!("'{n}'")).collect();
    names.sort();
    names.dedup();
    if names.is_empty() {
        none.to_string()
    } else {
        format!("{label}: {}", names.join(", "))
    }
}

fn quoted(name: Option<&String>, kind: &str, i: usize) -> String {
    match name {
        Some(n) => format!("{kind} '{n}'"),
        None => format!("{kind} #{i}"),
    }
}

fn mesh_name(m: &json::Mesh, i: usize) -> String {
    m.name.clone().unwrap_or_else(|| format!("mesh #{i}"))
}

pub(super) fn node_label(root: &json::Root, i: usize) -> String {
    quoted(root.nodes[i].name.as_ref(), "node", i)
}

pub(super) fn mesh_label(root: &json::Root, i: usize) -> String {
    quoted(root.meshes[i].name.as_ref(), "mesh", i)
}

fn material_label(root: &json::Root, i: usize) -> String {
    quoted(root.materials[i].name.as_ref(), "material", i)
}

/// One warning per unsupported-but-harmless feature.
fn feature_warnings(src: &Src, root: &json::Root, warnings: &mut Vec<String>) {
    let f = src.name();
    if !root.animations.is_empty() {
        warnings.push(format!(
            "{f}: {} animation(s) ignored (the scene is loaded at rest)",
            root.animations.len()
        ));
    }
    if !root.skins.is_empty() || root.nodes.iter().any(|n| n.skin.is_some()) {
        warnings.push(format!(
            "{f}: skins ignored (skinned meshes are loaded in their bind pose)"
        ));
    }
    let morph = root.meshes.iter().any(|m| {
        m.weights.is_some()
            || m.primitives
                .iter()
                .any(|p| p.targets.as_ref().is_some_and(|t| !t.is_empty()))
    }) || root.nodes.iter().any(|n| n.weights.is_some());
    if morph {
        warnings.push(format!(
            "{f}: morph targets ignored (meshes are loaded with their base shape)"
        ));
    }
    let colors = root.meshes.iter().any(|m| {
        m.primitives
            .iter()
            .any(|p| p.attributes.contains_key(&Checked::Valid(Semantic::Colors(0))))
    });
    if colors {
        warnings.push(format!("{f}: vertex colours ignored"));
    }
}

/// The nodes of the chosen scene, flattened with world transforms.
pub(super) struct Traversal {
    /// (node, mesh, world) in depth-first order.
    pub instances: Vec<(usize, usize, Mat4)>,
    /// (node, camera, world).
    pub cameras: Vec<(usize, usize, Mat4)>,
    /// (node, light, world).
    pub lights: Vec<(usize, usize, Mat4)>,
}

fn local_matrix(src: &Src, root: &json::Root, i: usize) -> Result<Mat4, SceneError> {
    let n = &root.nodes[i];
    let m = if let Some(m) = n.matrix {
        Mat4::from_cols_array(&m)
    } else {
        let t = Vec3::from(n.translation.unwrap_or([0.0; 3]));
        let r = n.rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
        let s = Vec3::from(n.scale.unwrap_or([1.0; 3]));
        let q = Quat::from_array(r);
        if !(q.length() > 1e-6) || !q.is_finite() {
            return Err(src.err(format!(
                "{}: rotation {r:?} is not a unit quaternion",
                node_label(root, i)
            )));
        }
        Mat4::from_scale_rotation_translation(s, q.normalize(), t)
    };
    if !m.is_finite() {
        return Err(src.err(format!("{}: transform has non-finite entries", node_label(root, i))));
    }
    Ok(m)
}

fn traverse(src: &Src, root: &json::Root, warnings: &mut Vec<String>) -> Result<Traversal, SceneError> {
    let roots: Vec<usize> = match root
        .scene
        .map(|s| s.value())
        .or(if root.scenes.is_empty() { None } else { Some(0) })
    {
        Some(s) => root.scenes[s].nodes.iter().map(|n| n.value()).collect(),
        None => {
            let mut is_child = vec![false; root.nodes.len()];
            for n in &root.nodes {
                for c in n.children.iter().flatten() {
                    is_child[c.value()] = true;
                }
            }
            if !root.nodes.is_empty() {
                warnings.push(format!(
                    "{}: no scene defined; using every node without a parent",
                    src.name()
                ));
            }
            (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut out = Traversal {
        instances: Vec::new(),
        cameras: Vec::new(),
        lights: Vec::new(),
    };
    // Explicit stack (no recursion depth limit); children pushed in reverse for pre-order.
    let mut stack: Vec<(usize, Mat4)> = roots.iter().rev().map(|&r| (r, Mat4::IDENTITY)).collect();
    while let Some((i, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[i], true) {
            return Err(src.err(format!(
                "{} is reached twice in the node hierarchy (a cycle, or more than one parent), which glTF forbids",
                node_label(root, i)
            )));
        }
        let world = parent * local_matrix(src, root, i)?;
        if !world.is_finite() {
            return Err(src.err(format!("{}: world transform overflows", node_label(root, i))));
        }
        let n = &root.nodes[i];
        if let Some(m) = n.mesh {
            out.instances.push((i, m.value(), world));
        }
        if let Some(c) = n.camera {
            out.cameras.push((i, c.value(), world));
        }
        if let Some(l) = n.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref()) {
            let count = root
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
                .map_or(0, |l| l.lights.len());
            if l.light.value() >= count {
                return Err(src.err(format!(
                    "{}: light {} does not exist",
                    node_label(root, i),
                    l.light.value()
                )));
            }
            out.lights.push((i, l.light.value(), world));
        }
        for c in n.children.iter().flatten().rev() {
            stack.push((c.value(), world));
        }
    }
    Ok(out)
}

fn check_color(what: &str, c: [f32; 3], max: Option<f32>) -> Result<Rgb, String> {
    for v in c {
        if !v.is_finite() || v < 0.0 || max.is_some_and(|m| v > m) {
            let range = match max {
                Some(m) => format!("in [0, {m}]"),
                None => "finite and non-negative".to_string(),
            };
            return Err(format!("{what} {c:?} must be {range}"));
        }
    }
    Ok(Vec3::from(c))
}

/// A glTF material's `baseColorTexture`: the glTF texture and the `TEXCOORD_n` set it reads.
#[derive(Clone, Copy, Debug)]
pub(super) struct BaseTex {
    texture: usize,
    tex_coord: u32,
}

/// The glTF materials, with the base colour factor in their BSDFs, and each one's
/// `baseColorTexture` (attached later by [`attach_textures`], after the overrides).
fn convert_materials(
    src: &Src,
    root: &json::Root,
    warnings: &mut Vec<String>,
) -> Result<(Vec<Material>, Vec<Option<BaseTex>>), SceneError> {
    let f = src.name();
    let mut out = Vec::with_capacity(root.materials.len());
    let mut base_tex = Vec::with_capacity(root.materials.len());
    for (i, m) in root.materials.iter().enumerate() {
        let label = material_label(root, i);
        let err = |what: String| src.err(format!("{label}: {what}"));
        let pbr = &m.pbr_metallic_roughness;
        let bc = pbr.base_color_factor.0;
        let base = check_color("baseColorFactor", [bc[0], bc[1], bc[2]], Some(1.0)).map_err(err)?;
        let ext = m.extensions.as_ref();
        let strength = ext
            .and_then(|e| e.emissive_strength.as_ref())
            .map_or(1.0, |s| s.emissive_strength.0);
        if !strength.is_finite() || strength < 0.0 {
            return Err(err(format!(
                "emissiveStrength {strength} must be finite and non-negative"
            )));
        }
        let emission = check_color("emissiveFactor", m.emissive_factor.0, None).map_err(err)? * strength;
        let transmission = ext.and_then(|e| e.transmission.as_ref());
        let ignored: Vec<&str> = [
            ("metallicRoughnessTexture", pbr.metallic_roughness_texture.is_some()),
            ("normalTexture", m.normal_texture.is_some()),
            ("occlusionTexture", m.occlusion_texture.is_some()),
            ("emissiveTexture", m.emissive_texture.is_some()),
            (
                "transmissionTexture",
                transmission.is_some_and(|t| t.transmission_texture.is_some()),
            ),
        ]
        .into_iter()
        .filter_map(|(name, present)| present.then_some(name))
        .collect();
        if !ignored.is_empty() {
            warnings.push(format!(
                "{f}: {label}: textures ignored: {} (the constant factors are used)",
                ignored.join(", ")
            ));
        }
        base_tex.push(pbr.base_color_texture.as_ref().map(|info| BaseTex {
            texture: info.index.value(),
            tex_coord: info.tex_coord,
        }));
        if !matches!(m.alpha_mode, Checked::Valid(json::material::AlphaMode::Opaque)) {
            warnings.push(format!("{f}: {label}: alphaMode ignored (treated as OPAQUE)"));
        }
        let bsdf = match transmission.map(|t| t.transmission_factor.0) {
            Some(t) if t > 0.0 => {
                if !(t <= 1.0) {
                    return Err(err(format!("transmissionFactor {t} must be in [0, 1]")));
                }
                if t < 1.0 {
                    warnings.push(format!(
                        "{f}: {label}: transmissionFactor {t} treated as 1 (smooth dielectric)"
                    ));
                }
                let ior = ext.and_then(|e| e.ior.as_ref()).map_or(1.5, |i| i.ior.0);
                if !(ior.is_finite() && ior >= 1.0) {
                    return Err(err(format!("ior {ior} must be finite and at least 1")));
                }
                Bsdf::Glass { ior, tint: base }
            }
            Some(t) if !(t == 0.0) => {
                return Err(err(format!("transmissionFactor {t} must be in [0, 1]")));
            }
            _ => Bsdf::Lambert { albedo: base },
        };
        out.push(Material {
            name: m.name.clone().unwrap_or_else(|| format!("material #{i}")),
            bsdf: Some(bsdf),
            emission,
            double_sided: m.double_sided,
            base_color_texture: None,
        });
    }
    Ok((out, base_tex))
}

/// Attaches the base-colour textures the materials still use after the overrides (Lambert
/// and Phong; glass keeps its factor-only tint, with a warning), decoding their images.
/// Returns, per glTF material, the `TEXCOORD_n` set its triangles need.
fn attach_textures(
    src: &Src,
    root: &json::Root,
    materials: &mut [Material],
    base_tex: &[Option<BaseTex>],
    loader: &mut TextureLoader,
    warnings: &mut Vec<String>,
) -> Result<Vec<Option<u32>>, SceneError> {
    let mut tex_coord = vec![None; base_tex.len()];
    for (i, bt) in base_tex.iter().enumerate() {
        let Some(bt) = bt else { continue };
        let label = material_label(root, i);
        match materials[i].bsdf {
            Some(Bsdf::Lambert { .. } | Bsdf::Phong { .. }) => {
                let t = loader.load(bt.texture, &format!("{label} baseColorTexture"), warnings)?;
                materials[i].base_color_texture = t;
                if t.is_some() {
                    tex_coord[i] = Some(bt.tex_coord);
                }
            }
            _ => warnings.push(format!(
                "{}: {label}: baseColorTexture ignored (glass is tinted by baseColorFactor only)",
                src.name()
            )),
        }
    }
    Ok(tex_coord)
}

fn apply_overrides(
    t: &TomlSrc,
    sc: &Sidecar,
    root: &json::Root,
    materials: &mut [Material],
    base_tex: &mut [Option<BaseTex>],
    loader: &mut TextureLoader,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    for (name, o) in &sc.materials {
        let targets: Vec<usize> = (0..root.materials.len())
            .filter(|&i| root.materials[i].name.as_deref() == Some(name.get_ref()))
            .collect();
        if targets.is_empty() {
            let names = root.materials.iter().filter_map(|m| m.name.as_deref());
            let list = name_list(names, "available", "the glTF has no named materials");
            return Err(t.err_at(
                name.span(),
                format!(
                    "[materials.{}]: no glTF material named '{}' ({list})",
                    name.get_ref(),
                    name.get_ref()
                ),
            ));
        }
        for i in targets {
            let who = format!("{} baseColorTexture", material_label(root, i));
            // The brightest texel the Phong diffuse colour can be multiplied by (1 untextured).
            let mut max_texel = |bt: BaseTex| -> Result<Rgb, SceneError> {
                Ok(match loader.load(bt.texture, &who, warnings)? {
                    Some(t) => loader.textures[t as usize].max_texel(),
                    None => Vec3::ONE,
                })
            };
            override_material(t, name, o, &mut materials[i], &mut base_tex[i], &mut max_texel)?;
        }
    }
    Ok(())
}

/// Applies one `[materials.NAME]` section to `m`. `base_tex` is the glTF base-colour texture,
/// kept only where the textured base colour still applies (Lambert without `albedo`, Phong
/// without `diffuse`).
fn override_material(
    t: &TomlSrc,
    name: &Spanned<String>,
    o: &MaterialToml,
    m: &mut Material,
    base_tex: &mut Option<BaseTex>,
    max_texel: &mut dyn FnMut(BaseTex) -> Result<Rgb, SceneError>,
) -> Result<(), SceneError> {
    let section = format!("[materials.{}]", name.get_ref());
    let bad = |span: std::ops::Range<usize>, what: String| t.err_at(span, format!("{section}: {what}"));
    let color = |v: &Spanned<Rgb3>, key: &str, max: Option<f32>| -> Result<Rgb, SceneError> {
        check_color(key, v.get_ref().0, max).map_err(|e| bad(v.span(), e))
    };
    // Which keys each kind takes.
    let present: Vec<(&str, std::ops::Range<usize>)> = [
        ("albedo", o.albedo.as_ref().map(|v| v.span())),
        ("diffuse", o.diffuse.as_ref().map(|v| v.span())),
        ("specular", o.specular.as_ref().map(|v| v.span())),
        ("exponent", o.exponent.as_ref().map(|v| v.span())),
        ("reflectance", o.reflectance.as_ref().map(|v| v.span())),
        ("ior", o.ior.as_ref().map(|v| v.span())),
        ("tint", o.tint.as_ref().map(|v| v.span())),
    ]
    .into_iter()
    .filter_map(|(k, s)| s.map(|s| (k, s)))
    .collect();
    let base = match &m.bsdf {
        Some(Bsdf::Lambert { albedo }) => *albedo,
        Some(Bsdf::Glass { tint, .. }) => *tint,
        _ => Vec3::splat(DEFAULT_ALBEDO),
    };
    if let Some(kind) = &o.kind {
        let allowed: &[&str] = match kind.get_ref().as_str() {
            "lambert" => &["albedo", "diffuse"],
            "phong" => &["diffuse", "specular", "exponent"],
            "mirror" => &["reflectance"],
            "glass" => &["ior", "tint"],
            other => {
                return Err(bad(
                    kind.span(),
                    format!("unknown kind '{other}' (expected lambert, phong, mirror or glass)"),
                ));
            }
        };
        if let Some((k, s)) = present.iter().find(|(k, _)| !allowed.contains(k)) {
            return Err(bad(
                s.clone(),
                format!(
                    "key '{k}' does not apply to kind = \"{}\" (it takes {})",
                    kind.get_ref(),
                    allowed.join(", ")
                ),
            ));
        }
        let bsdf = match kind.get_ref().as_str() {
            "lambert" => {
                if o.albedo.is_some() && o.diffuse.is_some() {
                    return Err(bad(kind.span(), "give either 'albedo' or 'diffuse', not both".into()));
                }
                let albedo = match o.albedo.as_ref().or(o.diffuse.as_ref()) {
                    Some(v) => {
                        *base_tex = None;
                        color(v, "albedo", Some(1.0))?
                    }
                    None => base,
                };
                Bsdf::Lambert { albedo }
            }
            "phong" => {
                let diffuse = match &o.diffuse {
                    Some(v) => {
                        *base_tex = None;
                        color(v, "diffuse", Some(1.0))?
                    }
                    None => base,
                };
                let specular = match &o.specular {
                    Some(v) => color(v, "specular", Some(1.0))?,
                    None => {
                        return Err(bad(kind.span(), "kind = \"phong\" needs 'specular'".into()));
                    }
                };
                let exponent = match &o.exponent {
                    Some(e) if e.get_ref().is_finite() && *e.get_ref() >= 0.0 => *e.get_ref(),
                    Some(e) => {
                        return Err(bad(
                            e.span(),
                            format!("exponent {} must be finite and >= 0", e.get_ref()),
                        ));
                    }
                    None => {
                        return Err(bad(kind.span(), "kind = \"phong\" needs 'exponent'".into()));
                    }
                };
                // With a base-colour texture the diffuse colour is diffuse × texel ≤ diffuse ×
                // the brightest texel.
                let (kd, what) = match *base_tex {
                    Some(bt) => (diffuse * max_texel(bt)?, "diffuse × brightest base colour texel"),
                    None => (diffuse, "diffuse"),
                };
                let sum = kd + specular;
                if sum.max_element() > 1.0 + 1e-6 {
                    let span = o.specular.as_ref().map_or(kind.span(), |s| s.span());
                    return Err(bad(
                        span,
                        format!(
                            "{what} + specular = [{}, {}, {}] exceeds 1: not energy conserving",
                            sum.x, sum.y, sum.z
                        ),
                    ));
                }
                Bsdf::Phong {
                    diffuse,
                    specular,
                    exponent,
                }
            }
            "mirror" => {
                let reflectance = match &o.reflectance {
                    Some(v) => color(v, "reflectance", Some(1.0))?,
                    None => Vec3::ONE,
                };
                *base_tex = None;
                Bsdf::Mirror { reflectance }
            }
            _ => {
                let ior = match &o.ior {
                    Some(v) if v.get_ref().is_finite() && *v.get_ref() > 0.0 => *v.get_ref(),
                    Some(v) => {
                        return Err(bad(v.span(), format!("ior {} must be finite and > 0", v.get_ref())));
                    }
                    None => 1.5,
                };
                let tint = match &o.tint {
                    Some(v) => color(v, "tint", Some(1.0))?,
                    None => Vec3::ONE,
                };
                *base_tex = None;
                Bsdf::Glass { ior, tint }
            }
        };
        m.bsdf = Some(bsdf);
    } else if let Some((k, s)) = present.first() {
        return Err(bad(
            s.clone(),
            format!("key '{k}' needs a 'kind' (lambert, phong, mirror or glass)"),
        ));
    }
    if let Some(e) = &o.emission {
        m.emission = color(e, "emission", None)?;
    }
    if let Some(d) = &o.double_sided {
        m.double_sided = *d.get_ref();
    }
    Ok(())
}

/// Triangles of the scene plus, for medium regions, what the media code needs.
pub(super) struct Geometry {
    pub triangles: Vec<Triangle>,
    pub regions: Vec<RegionInstance>,
}

fn build_triangles(
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

fn convert_light(
    src: &Src,
    root: &json::Root,
    node: usize,
    light: usize,
    world: Mat4,
    warnings: &mut Vec<String>,
) -> Result<PunctualLight, SceneError> {
    use json::extensions::scene::khr_lights_punctual::Type;
    let l = &root
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .expect("checked in traverse")
        .lights[light];
    let label = format!(
        "{} light {}",
        node_label(root, node),
        quoted(l.name.as_ref(), "", light).trim_start()
    );
    let err = |what: String| src.err(format!("{label}: {what}"));
    if !(l.intensity.is_finite() && l.intensity >= 0.0) {
        return Err(err(format!(
            "intensity {} must be finite and non-negative",
            l.intensity
        )));
    }
    let color = check_color("color", l.color, None).map_err(err)?;
    if l.range.is_some() {
        warnings.push(format!(
            "{}: {label}: range ignored (lights follow the inverse-square law)",
            src.name()
        ));
    }
    let intensity = color * l.intensity;
    let position = world.transform_point3(Vec3::ZERO);
    let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
    let dir_ok = || {
        if direction == Vec3::ZERO || !direction.is_finite() {
            Err(err("the node transform leaves no direction (zero scale)".into()))
        } else {
            Ok(direction)
        }
    };
    Ok(match l.type_ {
        Checked::Valid(Type::Point) => PunctualLight::Point { position, intensity },
        Checked::Valid(Type::Directional) => PunctualLight::Directional {
            direction: dir_ok()?,
            irradiance: intensity,
        },
        Checked::Valid(Type::Spot) => {
            let Some(spot) = &l.spot else {
                return Err(err("spot light without 'spot' properties".into()));
            };
            let (inner, outer) = (spot.inner_cone_angle, spot.outer_cone_angle);
            let half_pi = std::f32::consts::FRAC_PI_2;
            if !(inner >= 0.0 && inner <= outer && outer > 0.0 && outer <= half_pi + 1e-6) {
                return Err(err(format!(
                    "cone angles inner {inner} / outer {outer} must satisfy 0 <= inner <= outer <= pi/2, outer > 0"
                )));
            }
            PunctualLight::Spot {
                position,
                direction: dir_ok()?,
                intensity,
                cos_inner: inner.cos(),
                cos_outer: outer.cos(),
            }
        }
        Checked::Invalid => return Err(err("invalid light type".into())),
    })
}

/// Camera-to-world without scale: forward (−Z) and up (+Y) kept, right rebuilt.
fn rigid(world: Mat4) -> Option<Mat4> {
    let z = world.z_axis.truncate().normalize_or_zero();
    let y0 = world.y_axis.truncate();
    let y = (y0 - z * y0.dot(z)).normalize_or_zero();
    let x = y.cross(z);
    let pos = world.w_axis.truncate();
    let m = Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), pos.extend(1.0));
    (z != Vec3::ZERO && y != Vec3::ZERO && m.is_finite()).then_some(m)
}

fn choose_camera(
    src: &Src,
    root: &json::Root,
    trav: &Traversal,
    toml: Option<(&TomlSrc, &Sidecar)>,
    triangles: &[Triangle],
    lights: &[PunctualLight],
    warnings: &mut Vec<String>,
) -> Result<(Camera, Option<f32>), SceneError> {
    use json::camera::Type;
    let is_perspective = |c: usize| matches!(root.cameras[c].type_, Checked::Valid(Type::Perspective));
    let wanted = toml.and_then(|(t, sc)| sc.render.camera.as_ref().map(|c| (t, c)));
    let chosen: Option<&(usize, usize, Mat4)> = match wanted {
        Some((t, name)) => {
            let n = name.get_ref();
            let found = trav
                .cameras
                .iter()
                .find(|(node, _, _)| root.nodes[*node].name.as_deref() == Some(n))
                .or_else(|| {
                    trav.cameras
                        .iter()
                        .find(|(_, cam, _)| root.cameras[*cam].name.as_deref() == Some(n))
                });
            let Some(found) = found else {
                let names: Vec<String> = trav
                    .cameras
                    .iter()
                    .map(
                        |&(node, cam, _)| match (&root.nodes[node].name, &root.cameras[cam].name) {
                            (Some(n), _) => format!("'{n}'"),
                            (None, Some(c)) => format!("'{c}' (camera name)"),
                            (None, None) => format!("unnamed node #{node}"),
                        },
                    )
                    .collect();
                let list = if names.is_empty() {
                    "the glTF scene has no cameras".to_string()
                } else {
                    format!("camera nodes: {}", names.join(", "))
                };
                return Err(t.err_at(
                    name.span(),
                    format!("[render] camera = \"{n}\": no camera node or camera of that name ({list})"),
                ));
            };
            if !is_perspective(found.1) {
                return Err(t.err_at(
                    name.span(),
                    format!(
                        "[render] camera = \"{n}\": orthographic cameras are unsupported (use a perspective camera)"
                    ),
                ));
            }
            Some(found)
        }
        None => {
            let first = trav.cameras.iter().find(|(_, c, _)| is_perspective(*c));
            match (first, trav.cameras.first()) {
                (None, Some((node, _, _))) => {
                    return Err(src.err(format!(
                        "{}: orthographic cameras are unsupported and there is no perspective camera",
                        node_label(root, *node)
                    )));
                }
                (Some(f), Some(f0)) if f.0 != f0.0 => {
                    warnings.push(format!(
                        "{}: orthographic camera on {} skipped (unsupported); using {}",
                        src.name(),
                        node_label(root, f0.0),
                        node_label(root, f.0)
                    ));
                    Some(f)
                }
                (f, _) => f,
            }
        }
    };
    if let Some(&(node, cam, world)) = chosen {
        let label = node_label(root, node);
        let p = root.cameras[cam].perspective.as_ref().ok_or_else(|| {
            src.err(format!(
                "{label}: camera of type perspective without 'perspective' properties"
            ))
        })?;
        if !(p.yfov > 0.0 && p.yfov < std::f32::consts::PI) {
            return Err(src.err(format!("{label}: yfov {} must be in (0, pi) radians", p.yfov)));
        }
        let aspect = match p.aspect_ratio {
            Some(a) if a.is_finite() && a > 0.0 => Some(a),
            Some(a) => {
                return Err(src.err(format!("{label}: aspectRatio {a} must be finite and positive")));
            }
            None => None,
        };
        let to_world = rigid(world).ok_or_else(|| src.err(format!("{label}: the camera transform is singular")))?;
        return Ok((
            Camera {
                to_world,
                yfov: p.yfov,
                name: root.nodes[node].name.clone(),
            },
            aspect,
        ));
    }
    // No camera: look at the centre of the bounds from the +Z side.
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in triangles
        .iter()
        .flat_map(|t| t.p)
        .chain(lights.iter().filter_map(|l| l.position()))
    {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let (centre, radius) = if lo.x <= hi.x {
        (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-3))
    } else {
        (Vec3::ZERO, 1.0)
    };
    let yfov = DEFAULT_YFOV_DEGREES.to_radians();
    let eye = centre + Vec3::Z * (radius / (0.5 * yfov).sin());
    warnings.push(format!(
        "{}: no camera; using a default camera at ({}, {}, {}) looking at the scene's centre along -Z, yfov {DEFAULT_YFOV_DEGREES} degrees",
        src.name(),
        eye.x,
        eye.y,
        eye.z
    ));
    Ok((
        Camera {
            to_world: Mat4::from_translation(eye),
            yfov,
            name: None,
        },
        None,
    ))
}

fn render_settings(toml: Option<(&TomlSrc, &Sidecar)>, aspect: Option<f32>) -> Result<RenderSettings, SceneError> {
    let from_aspect = |v: f32| (v.round() as u32).clamp(1, MAX_RESOLUTION);
    let aspect = aspect.unwrap_or(1.0);
    let (w, h) = toml.map_or((None, None), |(_, sc)| {
        (sc.render.width.as_ref(), sc.render.height.as_ref())
    });
    if let Some((t, _)) = toml {
        for (key, v) in [("width", w), ("height", h)] {
            if let Some(v) = v.filter(|v| !(1..=MAX_RESOLUTION).contains(v.get_ref())) {
                return Err(t.err_at(
                    v.span(),
                    format!(
                        "[render] {key} = {}: absurd resolution (width and height must be 1..={MAX_RESOLUTION})",
                        v.get_ref()
                    ),
                ));
            }
        }
    }
    let (width, height) = match (w.map(|v| *v.get_ref()), h.map(|v| *v.get_ref())) {
        (Some(w), Some(h)) => (w, h),
        (Some(w), None) => (w, from_aspect(w as f32 / aspect)),
        (None, Some(h)) => (from_aspect(h as f32 * aspect), h),
        (None, None) => (from_aspect(DEFAULT_HEIGHT as f32 * aspect), DEFAULT_HEIGHT),
    };
    Ok(RenderSettings { width, height })
}
