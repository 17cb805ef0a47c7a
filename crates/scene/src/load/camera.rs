//! The camera (the glTF's, the sidecar's choice, or a made-up one) and the render settings.
use super::names::node_label;
use super::nodes::Traversal;
use super::sidecar::Sidecar;
use super::{Src, TomlSrc};
use crate::SceneError;
use crate::camera::Camera;
use crate::light::PunctualLight;
use crate::scene::{RenderSettings, Triangle};
use glam::{Mat4, Vec3};
use gltf::json::{self, validation::Checked};

/// Largest accepted image side.
pub(super) const MAX_RESOLUTION: u32 = 16384;
/// Image height when the sidecar does not give one.
pub(super) const DEFAULT_HEIGHT: u32 = 512;

/// Vertical field of view of the camera made up when the glTF has none.
pub(super) const DEFAULT_YFOV_DEGREES: f32 = 40.0;

/// Camera-to-world without scale: forward (−Z) and up (+Y) kept, right rebuilt.
pub(super) fn rigid(world: Mat4) -> Option<Mat4> {
    let z = world.z_axis.truncate().normalize_or_zero();
    let y0 = world.y_axis.truncate();
    let y = (y0 - z * y0.dot(z)).normalize_or_zero();
    let x = y.cross(z);
    let pos = world.w_axis.truncate();
    let m = Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), pos.extend(1.0));
    (z != Vec3::ZERO && y != Vec3::ZERO && m.is_finite()).then_some(m)
}

pub(super) fn choose_camera(
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

pub(super) fn render_settings(
    toml: Option<(&TomlSrc, &Sidecar)>,
    aspect: Option<f32>,
) -> Result<RenderSettings, SceneError> {
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
