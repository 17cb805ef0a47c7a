//! Camera-side gather data: one jittered camera ray per pixel per pass, followed through mirror
//! and glass chains and invisible medium boundaries, recorded as the points and segments where
//! the many-light estimators gather light.
//!
//! In a sharp medium ([`crate::components::is_sharp`]) a camera segment also starts a *walk*:
//! a point on it by free-flight sampling, a direction from its phase function, and what the
//! ray it scatters into meets is recorded as walk segments and a walk point, gathered like
//! camera records but credited to `Lmm` or `Lms` ([`walk_sharp_media`]); walk segments in
//! sharp media walk on in turn, until Russian roulette ends them.
//!
//! Throughput bookkeeping: a record's `throughput` is what radiance arriving there is multiplied
//! by on its way to the pixel. For a media segment it is the throughput at the segment's start
//! (its own transmittance is part of the estimate along it); for a shading point it includes the
//! transmittance of every medium the ray crossed to reach it. Emission seen directly (also
//! through specular chains) is added to `emitted`, per pixel.
use crate::{
    TraceScene,
    components::Component,
    context::{MAX_CROSSINGS, SurfaceHit},
    media,
};
use beamlight_scene::{Rgb, bsdf::Bsdf, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, scene::MediumId};
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
    /// The record of surface hit `sh` seen along `-wo` with `throughput`, in `medium`.
    fn new(sh: &SurfaceHit, wo: Vec3, pixel: u32, throughput: Rgb, medium: MediumId) -> Self {
        let ns = if sh.ns.dot(wo) < 0.0 { -sh.ns } else { sh.ns };
        Self {
            pos: sh.p.into(),
            material: sh.material,
            normal: ns.into(),
            tri: sh.tri,
            wo: wo.into(),
            pixel,
            throughput: throughput.into(),
            medium: medium.unwrap_or(NO_MEDIUM),
            uv: sh.uv.unwrap_or_default().into(),
            _pad2: [0; 2],
        }
    }

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
    /// Stretches of the rays that walks through sharp media scattered into
    /// ([`walk_sharp_media`]); everything gathered along them is `Lmm`.
    pub walk_segments: Vec<MediaSegment>,
    /// The diffuse or glossy surfaces those rays reached, and the component everything
    /// gathered at each is credited to (`Lms`, or `Lmm` after two walk scatterings).
    pub walk_points: Vec<(ShadingPoint, Component)>,
    /// Emitted radiance seen directly, per pixel (one jittered sample).
    pub emitted: Vec<Rgb>,
}

#[derive(Clone, Copy, Debug)]
pub struct CameraPathSettings {
    /// Specular bounces (and walk scatterings) after which Russian roulette starts.
    pub rr_depth: u32,
    /// Whether camera segments in sharp media start walks ([`walk_sharp_media`]); off for
    /// camera samples that only estimate direct light.
    pub walks: bool,
}

impl Default for CameraPathSettings {
    fn default() -> Self {
        Self {
            rr_depth: 8,
            walks: true,
        }
    }
}

/// The pixels a pass covers: every one, or (a time budget's shortened last pass) a share of
/// them, each pixel in or out by a hash of the pass and its index. Scattered rather than a
/// band of rows, so that the pixels with one sample more do not show as a band of less noise.
/// The films count each pixel's own samples ([`PixelShare::contains`] says which).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelShare {
    /// A pixel is in when its hash is below this, out of 2³² (2³²: all of them).
    threshold: u64,
}

impl PixelShare {
    pub const ALL: PixelShare = PixelShare { threshold: 1 << 32 };

    /// About `share` of the pixels (clamped to [0, 1]).
    pub fn of(share: f64) -> PixelShare {
        let share = if share.is_nan() { 0.0 } else { share.clamp(0.0, 1.0) };
        PixelShare {
            threshold: (share * (1u64 << 32) as f64).round() as u64,
        }
    }

    pub fn is_all(&self) -> bool {
        self.threshold >= 1 << 32
    }

    /// The expected share of the pixels covered.
    pub fn share(&self) -> f64 {
        self.threshold as f64 / (1u64 << 32) as f64
    }

    /// Whether pass `pass` covers `pixel`. The hash is the pass's and the pixel's alone (no
    /// seed), so a film can tell which pixels a partial pass covered from its index.
    pub fn contains(&self, pass: u32, pixel: u32) -> bool {
        self.is_all() || (pixel_hash(pass, pixel) as u64) < self.threshold
    }
}

fn pixel_hash(pass: u32, pixel: u32) -> u32 {
    beamlight_scene::rng::hash4(0x0b5e_55ed, pass, pixel, 0)
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
    trace_camera_pixels(ts, settings, width, height, PixelShare::ALL, seed, pass)
}

/// [`trace_camera_paths`] for the pixels of `pixels` alone (the others see nothing: their
/// `emitted` stays zero and they leave no records). A covered pixel's camera path is the one
/// the whole pass traces for it.
pub fn trace_camera_pixels(
    ts: &TraceScene,
    settings: &CameraPathSettings,
    width: u32,
    height: u32,
    pixels: PixelShare,
    seed: u32,
    pass: u32,
) -> GatherSet {
    let cam = &ts.scene.camera;
    // Only scenes with a sharp medium walk.
    let walks = settings.walks && ts.scene.media.iter().any(|m| crate::components::is_sharp(m.g));
    // Bands of TILE rows in parallel, each into its own set, its pixels in TILE × TILE tiles
    // (so that consecutive media segments are neighbours on the image, as the flat draw's
    // groups assume: `light_tree::FLAT_GROUP`); joined in band order, so the records' order
    // (which keys their random streams) is the same on any number of threads. Shading points
    // share nothing between records: they are put back in row order (a stable sort by pixel
    // keeps a pixel's own in path order), so their streams stay those of a row-by-row trace.
    const TILE: u32 = 4;
    let bands: Vec<GatherSet> = (0..height.div_ceil(TILE))
        .into_par_iter()
        .map(|band| {
            let rows = band * TILE..((band + 1) * TILE).min(height);
            let mut part = GatherSet {
                width,
                height: rows.len() as u32,
                emitted: vec![Rgb::ZERO; (width * rows.len() as u32) as usize],
                ..Default::default()
            };
            for x0 in (0..width).step_by(TILE as usize) {
                for y in rows.clone() {
                    for x in x0..(x0 + TILE).min(width) {
                        let pixel = y * width + x;
                        if !pixels.contains(pass, pixel) {
                            continue;
                        }
                        let mut s = Sampler::new(seed, pass, pixel);
                        let j = s.next_2d();
                        let film = Vec2::new((x as f32 + j.x) / width as f32, (y as f32 + j.y) / height as f32);
                        let d = cam.direction(film, width as f32 / height as f32);
                        let first = part.media_segments.len();
                        part.emitted[((y - rows.start) * width + x) as usize] = trace_one(
                            ts,
                            settings,
                            pixel,
                            cam.position(),
                            d,
                            ts.camera_medium,
                            &mut s,
                            &mut part,
                        );
                        if walks {
                            // A stream of its own, so that walks leave the camera paths'
                            // streams as they are.
                            let mut sw = Sampler::new(seed ^ WALK_SALT, pass, pixel);
                            let walk = (&mut part.walk_segments, &mut part.walk_points);
                            walk_sharp_media(ts, settings, &part.media_segments[first..], &mut sw, walk);
                        }
                    }
                }
            }
            part.shading_points.sort_by_key(|sp| sp.pixel);
            part
        })
        .collect();
    let mut set = GatherSet {
        width,
        height,
        shading_points: Vec::with_capacity(bands.iter().map(|r| r.shading_points.len()).sum()),
        media_segments: Vec::with_capacity(bands.iter().map(|r| r.media_segments.len()).sum()),
        walk_segments: Vec::with_capacity(bands.iter().map(|r| r.walk_segments.len()).sum()),
        walk_points: Vec::with_capacity(bands.iter().map(|r| r.walk_points.len()).sum()),
        emitted: Vec::with_capacity((width * height) as usize),
    };
    for row in bands {
        set.shading_points.extend(row.shading_points);
        set.media_segments.extend(row.media_segments);
        set.walk_segments.extend(row.walk_segments);
        set.walk_points.extend(row.walk_points);
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
            // Finite and positive wherever something can scatter (`media::extent`, tested):
            // a segment skipped here holds no light.
            if m.scatters() && length.is_finite() && length > 0.0 {
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
            set.shading_points
                .push(ShadingPoint::new(&sh, wo, pixel, throughput, medium));
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

/// Salt of the walks' random streams.
const WALK_SALT: u32 = 0x6a09_e667;

/// Walks on from the camera segments `from` through sharp media (see [`crate::components`]):
/// each segment in a sharp medium picks a scattering point v by free-flight sampling (none
/// when the flight passes its end) and a direction from the phase function there. The ray from
/// v, followed through invisible medium boundaries, is recorded stretch by stretch as walk
/// segments, and its first diffuse or glossy surface as a walk point (a mirror, glass, an
/// emitter or nothing ends it: those paths are caustics or direct light at v, which v's own
/// estimators supply). Stretches in sharp media walk on in turn. v2, the walk's next vertex,
/// lies on one of these records, so each is credited to the class of (v1, v2): `Lmm` for a
/// stretch; for the surface `Lms` when v was v1 (a camera segment), `Lmm` when v was itself on
/// a walk stretch (then v1 and v2 are both in media). Free-flight and HG sampling are exact,
/// so a record's throughput is its parent's times the single-scattering albedo and the
/// transmittance of the stretches before it; Russian roulette after `rr_depth` scatterings
/// keeps walks finite and unbiased.
fn walk_sharp_media(
    ts: &TraceScene,
    settings: &CameraPathSettings,
    from: &[MediaSegment],
    s: &mut Sampler,
    (walk_segments, walk_points): (&mut Vec<MediaSegment>, &mut Vec<(ShadingPoint, Component)>),
) {
    let scene = &ts.scene;
    // (segment, scatterings before it), depth first.
    let mut todo: Vec<(MediaSegment, u32)> = from.iter().rev().map(|&seg| (seg, 0)).collect();
    while let Some((seg, depth)) = todo.pop() {
        let m = &scene.media[seg.medium as usize];
        if !crate::components::is_sharp(m.g) {
            continue;
        }
        let (o, d) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
        let mut throughput = Rgb::from(seg.throughput);
        let media::MediumEvent::Scatter { t, weight } = media::sample_distance(m, o, d, seg.length, throughput, s)
        else {
            continue;
        };
        throughput *= weight;
        let depth = depth + 1;
        if depth >= settings.rr_depth {
            let q = throughput.max_element().min(0.95);
            if !(s.next_1d() < q) {
                continue;
            }
            throughput /= q;
        }
        // Only an exact zero ends the walk here: a NaN goes on into the records, where the
        // estimates' `admit` counts it.
        if throughput == Rgb::ZERO {
            continue;
        }
        let wi = HenyeyGreenstein { g: m.g }.sample(-d, s.next_2d()).wi;
        let at_surface = if depth == 1 { Component::Lms } else { Component::Lmm };
        // The scattered ray, stretch by stretch through invisible boundaries.
        let (mut o, mut medium) = (o + d * t, Some(seg.medium));
        for _ in 0..=MAX_CROSSINGS {
            let hit = ts.bvh.closest_hit(o, wi, f32::INFINITY);
            if let Some(mi) = medium {
                let medium_here = &scene.media[mi as usize];
                let length = media::extent(medium_here, o, hit.map_or(f32::INFINITY, |h| h.t));
                if medium_here.scatters() && length.is_finite() && length > 0.0 {
                    let stretch = MediaSegment {
                        origin: o.into(),
                        length,
                        dir: wi.into(),
                        medium: mi,
                        throughput: throughput.into(),
                        pixel: seg.pixel,
                    };
                    walk_segments.push(stretch);
                    todo.push((stretch, depth));
                }
                throughput *= ts.medium_transmittance(medium, o, wi, length, s);
            }
            let Some(h) = hit else { break };
            if throughput == Rgb::ZERO {
                break;
            }
            let sh = ts.surface(&h);
            match scene.bsdf_at(sh.material, sh.uv) {
                None => {
                    medium = ts.medium_beyond(&sh, wi, medium);
                    o = sh.spawn(wi);
                }
                Some(bsdf) => {
                    if !bsdf.is_delta() {
                        let sp = ShadingPoint::new(&sh, -wi, seg.pixel, throughput, medium);
                        walk_points.push((sp, at_surface));
                    }
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A share covers about that share of the pixels, and two passes' shares are independent
    /// draws (their overlap is the product), so that partial passes spread over the image.
    /// Tolerance: 5 binomial standard deviations of the counts (a false failure about once
    /// in 10⁶ runs; the hashes are fixed, so it either always passes or always fails). Catches
    /// a share off by more than ~1.5 % of 9216 pixels, and a hash that ignores the pass (two
    /// passes would then cover the same pixels: overlap 0.3 instead of 0.09).
    #[test]
    fn a_share_covers_its_share_of_the_pixels_independently_per_pass() {
        let n = 96 * 96u32;
        let within = |count: usize, p: f64| {
            let sd = (n as f64 * p * (1.0 - p)).sqrt();
            (count as f64 - n as f64 * p).abs() <= 5.0 * sd
        };
        let share = PixelShare::of(0.3);
        let a: Vec<bool> = (0..n).map(|i| share.contains(5, i)).collect();
        let b: Vec<bool> = (0..n).map(|i| share.contains(6, i)).collect();
        let count = |v: &[bool]| v.iter().filter(|&&x| x).count();
        assert!(
            within(count(&a), 0.3) && within(count(&b), 0.3),
            "{} {}",
            count(&a),
            count(&b)
        );
        let both = a.iter().zip(&b).filter(|(x, y)| **x && **y).count();
        assert!(within(both, 0.09), "{both}");
        assert!((0..n).all(|i| PixelShare::ALL.contains(5, i) && PixelShare::of(1.0).contains(5, i)));
        assert!((0..n).all(|i| !PixelShare::of(0.0).contains(5, i)));
        assert!(!PixelShare::of(0.999).is_all() && PixelShare::of(1.5).is_all());
        assert_eq!(PixelShare::of(f64::NAN), PixelShare::of(0.0));
    }
}
