//! Camera-side gather data: one jittered camera ray per pixel per pass, followed through mirror
//! and glass chains and invisible medium boundaries, recorded as the points and segments where
//! the many-light estimators gather light.
//!
//! Throughput bookkeeping: a record's `throughput` is what radiance arriving there is multiplied
//! by on its way to the pixel. For a media segment it is the throughput at the segment's start
//! (its own transmittance is part of the estimate along it); for a shading point it includes the
//! transmittance of every medium the ray crossed to reach it. Emission seen directly (also
//! through specular chains) is added to `emitted`, per pixel.
use crate::{TraceScene, context::MAX_CROSSINGS, media};
use beamlight_scene::{Rgb, bsdf::Bsdf, frame::Frame, rng::Sampler, scene::MediumId};
use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// A diffuse or glossy surface point seen from the camera (possibly through specular bounces).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ShadingPoint {
    pub pos: [f32; 3],
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Shading normal, on the side of `wo`.
    pub normal: [f32; 3],
    /// Index into `Scene::triangles`.
    pub tri: u32,
    /// Unit direction towards the camera (along the path).
    pub wo: [f32; 3],
    /// Pixel index (row-major, row 0 at the top).
    pub pixel: u32,
    pub throughput: [f32; 3],
    /// The medium around the point (on the side of `wo`), [`NO_MEDIUM`] for vacuum.
    pub medium: u32,
    /// Texture coordinates (zero when the material is untextured).
    pub uv: [f32; 2],
    pub _pad2: [u32; 2],
}

/// `ShadingPoint::medium` of a point in vacuum.
pub const NO_MEDIUM: u32 = u32::MAX;

impl ShadingPoint {
    pub fn medium(&self) -> MediumId {
        (self.medium != NO_MEDIUM).then_some(self.medium)
    }
}

/// A stretch of a camera ray through one medium.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MediaSegment {
    pub origin: [f32; 3],
    /// Length of the stretch (∞ never: unbounded stretches are cut where the medium ends or
    /// where transmittance makes the rest negligible, see [`trace_camera_paths`]).
    pub length: f32,
    /// Unit direction of travel (away from the camera).
    pub dir: [f32; 3],
    /// Index into `Scene::media`.
    pub medium: u32,
    /// Throughput at `origin`.
    pub throughput: [f32; 3],
    pub pixel: u32,
}

/// One pass's camera gather data.
#[derive(Clone, Debug, Default)]
pub struct GatherSet {
    pub width: u32,
    pub height: u32,
    pub shading_points: Vec<ShadingPoint>,
    pub media_segments: Vec<MediaSegment>,
    /// Emitted radiance seen directly, per pixel (one jittered sample).
    pub emitted: Vec<Rgb>,
}

#[derive(Clone, Copy, Debug)]
pub struct CameraPathSettings {
    /// Specular bounces after which Russian roulette starts.
    pub rr_depth: u32,
}

impl Default for CameraPathSettings {
    fn default() -> Self {
        Self { rr_depth: 8 }
    }
}

/// Traces one camera ray per pixel for pass `pass` with the random stream
/// `(seed, pass, pixel)`. A ray that leaves the scene inside an unbounded medium is cut as
/// [`media::extent`] says.
pub fn trace_camera_paths(
    ts: &TraceScene,
    settings: &CameraPathSettings,
    width: u32,
    height: u32,
    seed: u32,
    pass: u32,
) -> GatherSet {
    let cam = &ts.scene.camera;
    // Rows in parallel, each into its own set; joined in row order, so the records' order
    // (which keys their random streams) is the same on any number of threads.
    let rows: Vec<GatherSet> = (0..height)
        .into_par_iter()
        .map(|y| {
            let mut row = GatherSet {
                width,
                height: 1,
                emitted: vec![Rgb::ZERO; width as usize],
                ..Default::default()
            };
            for x in 0..width {
                let pixel = y * width + x;
                let mut s = Sampler::new(seed, pass, pixel);
                let j = s.next_2d();
                let film = Vec2::new((x as f32 + j.x) / width as f32, (y as f32 + j.y) / height as f32);
                let d = cam.direction(film, width as f32 / height as f32);
                row.emitted[x as usize] = trace_one(
                    ts,
                    settings,
                    pixel,
                    cam.position(),
                    d,
                    ts.camera_medium,
                    &mut s,
                    &mut row,
                );
            }
            row
        })
        .collect();
    let mut set = GatherSet {
        width,
        height,
        shading_points: Vec::with_capacity(rows.iter().map(|r| r.shading_points.len()).sum()),
        media_segments: Vec::with_capacity(rows.iter().map(|r| r.media_segments.len()).sum()),
        emitted: Vec::with_capacity((width * height) as usize),
    };
    for row in rows {
        set.shading_points.extend(row.shading_points);
        set.media_segments.extend(row.media_segments);
        set.emitted.extend(row.emitted);
    }
    set
}

/// Follows one camera ray, pushing its records into `set`; returns the emission it saw.
#[allow(clippy::too_many_arguments)]
fn trace_one(
    ts: &TraceScene,
    settings: &CameraPathSettings,
    pixel: u32,
    mut o: Vec3,
    mut d: Vec3,
    mut medium: MediumId,
    s: &mut Sampler,
    set: &mut GatherSet,
) -> Rgb {
    let scene = &ts.scene;
    let mut emitted = Rgb::ZERO;
    let mut throughput = Rgb::ONE;
    let mut bounces = 0u32;
    let mut crossings = 0u32;
    loop {
        // Surface data is built only if the ray gets there (not when it scatters in a medium).
        let hit = ts.bvh.closest_hit(o, d, f32::INFINITY);
        if let Some(mi) = medium {
            let m = &scene.media[mi as usize];
            let length = media::extent(m, o, hit.map_or(f32::INFINITY, |h| h.t));
            if length.is_finite() && length > 0.0 {
                set.media_segments.push(MediaSegment {
                    origin: o.into(),
                    length,
                    dir: d.into(),
                    medium: mi,
                    throughput: throughput.into(),
                    pixel,
                });
            }
            throughput *= ts.medium_transmittance(medium, o, d, length, s);
            if throughput == Rgb::ZERO {
                return emitted;
            }
        }
        let Some(h) = hit else { return emitted };
        let sh = ts.surface(&h);
        let mat = ts.material(&sh);
        if mat.is_emissive() && (mat.double_sided || sh.ng.dot(d) < 0.0) {
            emitted += throughput * mat.emission;
        }
        let Some(bsdf) = scene.bsdf_at(sh.material, sh.uv) else {
            medium = ts.medium_beyond(&sh, d, medium);
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                return emitted;
            }
            o = sh.spawn(d);
            continue;
        };
        let wo = -d;
        if !bsdf.is_delta() {
            let ns = if sh.ns.dot(wo) < 0.0 { -sh.ns } else { sh.ns };
            let uv = sh.uv.unwrap_or_default();
            set.shading_points.push(ShadingPoint {
                pos: sh.p.into(),
                material: sh.material,
                normal: ns.into(),
                tri: sh.tri,
                wo: wo.into(),
                pixel,
                throughput: throughput.into(),
                medium: medium.unwrap_or(NO_MEDIUM),
                uv: uv.into(),
                _pad2: [0; 2],
            });
            return emitted;
        }
        // Mirror or glass: follow the specular chain.
        let frame = Frame::from_normal(sh.ns);
        let Some(bs) = bsdf.sample(frame.to_local(wo), s.next_2d(), s.next_1d()) else {
            return emitted;
        };
        let wi = frame.to_world(bs.wi);
        if !matches!(bsdf, Bsdf::Glass { .. }) && sh.ng.dot(wi) * sh.ng.dot(wo) <= 0.0 {
            return emitted;
        }
        throughput *= bs.weight;
        bounces += 1;
        if bounces >= settings.rr_depth {
            let q = throughput.max_element().min(0.95);
            if s.next_1d() >= q {
                return emitted;
            }
            throughput /= q;
        }
        medium = ts.medium_beyond(&sh, wi, medium);
        o = sh.spawn(wi);
        d = wi;
    }
}
