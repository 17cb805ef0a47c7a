//! Building a [`Scene`] from a parsed glTF and its optional sidecar, concept by concept:
//! nodes, materials, triangles, media, lights, camera.
use super::camera::{choose_camera, render_settings};
use super::gltf_read;
use super::images::TextureLoader;
use super::lights::convert_light;
use super::materials::{apply_overrides, attach_textures, convert_materials};
use super::media::{self, MediaPlan};
use super::names::mesh_name;
use super::nodes::traverse;
use super::sidecar::Sidecar;
use super::triangles::build_triangles;
use super::{Src, TomlSrc};
use crate::{Scene, SceneError};
use gltf::json::{self, mesh::Semantic, validation::Checked};
use std::path::Path;

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
