//! glTF materials to BSDFs, the sidecar's `[materials]` overrides, and base-colour textures.
use super::images::TextureLoader;
use super::names::{material_label, name_list};
use super::sidecar::{MaterialToml, Rgb3, Sidecar};
use super::{Src, TomlSrc};
use crate::bsdf::{Bsdf, Material};
use crate::{Rgb, SceneError};
use glam::Vec3;
use gltf::json::{self, validation::Checked};
use toml::Spanned;

/// Albedo of the material given to primitives without one: the glTF default material has
/// baseColorFactor 1, which maps to a white Lambert surface.
pub(super) const DEFAULT_ALBEDO: f32 = 1.0;

pub(super) fn check_color(what: &str, c: [f32; 3], max: Option<f32>) -> Result<Rgb, String> {
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
pub(super) fn convert_materials(
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
pub(super) fn attach_textures(
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

pub(super) fn apply_overrides(
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
pub(super) fn override_material(
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
