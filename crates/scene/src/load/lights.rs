//! KHR_lights_punctual lights to the scene's punctual lights.
use super::Src;
use super::materials::check_color;
use super::names::{node_label, quoted};
use crate::SceneError;
use crate::light::PunctualLight;
use glam::{Mat4, Vec3};
use gltf::json::{self, validation::Checked};

pub(super) fn convert_light(
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
