//! The CPU's estimates at a pass's gather records, written once for both kinds of record: a
//! shading point on a surface and a camera segment through a medium each gather the same two
//! light sets (the point-like VPLs/VSLs and the ray-like VRLs/VBLs) and one caustic map, through
//! estimators and into components of their kind ([`Record`]).
use beamlight_scene::{Rgb, Scene, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    components::{Component, gathers_in_medium},
    direct,
    gather::GatherInputs,
    light_paths::{LightSegment, SurfaceVertex},
    light_tree::{Draw, Drawing, FLAT_GROUP, LightTree, Receiver, flat_draw_receiver, flat_group_representative},
    streams::{self, GatherKind},
    vbl::{self, VblSettings, Walls},
    vpl, vrl,
};
use rayon::prelude::*;
use std::time::Instant;

const N: usize = Component::ALL.len();

/// How the pass's virtual lights are evaluated: beams and spheres of squared radius `r2`
/// (`vbl`), or rays and points with the inverse-square falloff clamped at `clamp` (`vrl`).
pub struct Estimators<'a> {
    beams: bool,
    r2: f32,
    vbl: &'a VblSettings,
    clamp: f32,
}

/// A kind of gather record, as the CPU estimators see it.
pub trait Record: Sync {
    /// The component (and gather kind, which names its random streams) of the light arriving
    /// from point-like and from ray-like virtual lights, and of the caustic map's.
    const FROM_POINTS: (Component, GatherKind);
    const FROM_RAYS: (Component, GatherKind);
    const CAUSTIC: Component;
    /// Direct light's stream kind ([`direct_stream`]).
    const DIRECT_STREAM: u32;
    fn pixel(&self) -> u32;
    fn receiver(&self, scene: &Scene) -> Receiver;
    /// The receiver a flat draw of ray-like lights weighs them for.
    fn flat_receiver(&self, scene: &Scene) -> Receiver {
        self.receiver(scene)
    }
    /// Whether virtual lights are gathered here at all (not in a medium whose phase function
    /// is a near-delta, whose light the walks carry instead).
    fn gathers(&self, ts: &TraceScene) -> bool;
    fn direct(&self, ts: &TraceScene, s: &mut Sampler) -> Rgb;
    /// Light from VPL `v`; `walls` are the walls next to it when the estimators are beams.
    fn point_light(&self, ts: &TraceScene, v: &SurfaceVertex, walls: &Walls, e: &Estimators, s: &mut Sampler) -> Rgb;
    fn ray_light(&self, ts: &TraceScene, v: &LightSegment, e: &Estimators, s: &mut Sampler) -> Rgb;
}

impl Record for ShadingPoint {
    const FROM_POINTS: (Component, GatherKind) = (Component::Lss, GatherKind::VplToSurface);
    const FROM_RAYS: (Component, GatherKind) = (Component::Lsm, GatherKind::VrlToSurface);
    const CAUSTIC: Component = Component::CausticSurface;
    const DIRECT_STREAM: u32 = 0;

    fn pixel(&self) -> u32 {
        self.pixel
    }

    fn receiver(&self, scene: &Scene) -> Receiver {
        Receiver::at_point(scene, self)
    }

    fn gathers(&self, _ts: &TraceScene) -> bool {
        true
    }

    fn direct(&self, ts: &TraceScene, s: &mut Sampler) -> Rgb {
        direct::direct_at_surface(ts, self, s)
    }

    fn point_light(&self, ts: &TraceScene, v: &SurfaceVertex, walls: &Walls, e: &Estimators, s: &mut Sampler) -> Rgb {
        if e.beams {
            vbl::vsl_to_surface_within(ts, self, v, walls, e.r2, e.vbl, s)
        } else {
            vpl::vpl_to_surface(ts, self, v, e.clamp, s)
        }
    }

    fn ray_light(&self, ts: &TraceScene, v: &LightSegment, e: &Estimators, s: &mut Sampler) -> Rgb {
        if e.beams {
            vbl::vbl_to_surface(ts, self, v, e.r2, e.vbl, s)
        } else {
            vrl::vrl_to_surface(ts, self, v, e.clamp, s)
        }
    }
}

impl Record for MediaSegment {
    const FROM_POINTS: (Component, GatherKind) = (Component::Lms, GatherKind::VplToMedia);
    const FROM_RAYS: (Component, GatherKind) = (Component::Lmm, GatherKind::VrlToMedia);
    const CAUSTIC: Component = Component::CausticVolume;
    const DIRECT_STREAM: u32 = 1;

    fn pixel(&self) -> u32 {
        self.pixel
    }

    fn receiver(&self, scene: &Scene) -> Receiver {
        Receiver::along_segment(scene, self)
    }

    fn flat_receiver(&self, scene: &Scene) -> Receiver {
        flat_draw_receiver(scene, self)
    }

    fn gathers(&self, ts: &TraceScene) -> bool {
        gathers_in_medium(ts.scene.media[self.medium as usize].g)
    }

    fn direct(&self, ts: &TraceScene, s: &mut Sampler) -> Rgb {
        direct::direct_in_medium(ts, self, s)
    }

    fn point_light(&self, ts: &TraceScene, v: &SurfaceVertex, walls: &Walls, e: &Estimators, s: &mut Sampler) -> Rgb {
        if e.beams {
            vbl::vsl_to_media_within(ts, self, v, walls, e.r2, e.vbl, s)
        } else {
            vpl::vpl_to_media(ts, self, v, e.clamp, s)
        }
    }

    fn ray_light(&self, ts: &TraceScene, v: &LightSegment, e: &Estimators, s: &mut Sampler) -> Rgb {
        if e.beams {
            vbl::vbl_to_media(ts, self, v, e.r2, e.vbl, s)
        } else {
            vrl::vrl_to_media(ts, self, v, e.clamp, s)
        }
    }
}

/// One record's estimates per component ([`Component::ALL`] order), their CPU seconds and
/// discards.
pub struct RecordEstimate {
    pub pixel: u32,
    pub value: [Rgb; N],
    pub seconds: [f64; N],
    pub discarded: [u64; N],
}

/// A caustic map's radiance at record `i`, divided by its light path count.
pub type CausticLookup<'a, R> = &'a (dyn Fn(usize, &R) -> Rgb + Sync);

/// What a pass's CPU gathers share.
pub struct PassGathers<'a> {
    pub ts: &'a TraceScene,
    /// The records, the virtual lights and how they are gathered: what the GPU kernels read.
    pub inputs: &'a GatherInputs<'a>,
    /// The render's seed (direct light's streams at walk records).
    pub seed: u32,
    /// The components the pass computes.
    pub computed: [bool; N],
    /// The virtual-light gathers run here (no GPU takes them).
    pub virtual_lights: bool,
    pub selection: Option<&'a Selection>,
    /// Virtual beam and spherical lights (`vbl`), else rays and points.
    pub beams: bool,
}

impl RecordEstimate {
    fn new(pixel: u32) -> Self {
        Self {
            pixel,
            value: [Rgb::ZERO; N],
            seconds: [0.0; N],
            discarded: [0; N],
        }
    }

    /// Adds `v` to component `k`, [`admit`]ted.
    fn add(&mut self, k: usize, v: Rgb) {
        self.value[k] += admit(v, &mut self.discarded[k]);
    }
}

/// The two light sets of a pass's gathers.
#[derive(Clone, Copy)]
enum LightSet {
    /// VPLs or VSLs.
    Points,
    /// VRLs or VBLs.
    Rays,
}

impl PassGathers<'_> {
    /// Every record's estimates, in parallel: a walk record's own direct light, the
    /// virtual-light gathers (when on the CPU), and the caustic map's radiance, `caustic(i,
    /// record)` (already divided by its path count), when there is a map. `credits[i]` is the
    /// component a walk record's every estimate is credited to ([`credited`]).
    pub fn estimate<R: Record>(
        &self,
        records: &[R],
        credits: &[Option<Component>],
        caustic: Option<CausticLookup<R>>,
    ) -> Vec<RecordEstimate> {
        let ts = self.ts;
        records
            .par_chunks(FLAT_GROUP)
            .enumerate()
            .flat_map_iter(|(group, chunk)| {
                let first = group * FLAT_GROUP;
                let mut shared = self.shared_flat_masses::<R>(chunk, &credits[first..first + chunk.len()]);
                chunk.iter().enumerate().map(move |(o, record)| {
                    let i = first + o;
                    let mut e = RecordEstimate::new(record.pixel());
                    let credit = credits[i];
                    let want = |component: Component| self.computed[credited(component, credit) as usize];
                    if let Some(k) = credit.map(|k| k as usize).filter(|&k| self.computed[k]) {
                        // A walk record's direct light; the camera's records' is part of
                        // `direct_light`.
                        let mut sd = direct_stream(self.seed, self.inputs.pass, R::DIRECT_STREAM, i);
                        let v = timed(&mut e.seconds[k], || record.direct(ts, &mut sd));
                        e.add(k, v);
                    }
                    if self.virtual_lights && record.gathers(ts) {
                        let rx = self.selection.map(|sel| (sel, record.receiver(&ts.scene)));
                        if want(R::FROM_POINTS.0) {
                            self.gather(&mut e, (i, record), credit, rx.as_ref(), LightSet::Points, None);
                        }
                        if want(R::FROM_RAYS.0) {
                            let masses = shared.as_mut().map(|(masses, seconds)| {
                                // The group's masses are timed once, at the first record that
                                // draws by them.
                                e.seconds[credited(R::FROM_RAYS.0, credit) as usize] += std::mem::take(seconds);
                                masses.as_slice()
                            });
                            self.gather(&mut e, (i, record), credit, rx.as_ref(), LightSet::Rays, masses);
                        }
                    }
                    if let Some(caustic) = caustic {
                        let k = credited(R::CAUSTIC, credit) as usize;
                        let v = timed(&mut e.seconds[k], || caustic(i, record));
                        e.add(k, injected(v, self.poison(i, 1)));
                    }
                    e
                })
            })
            .collect()
    }

    /// The flat draw's masses ([`LightTree::flat_masses`]) that a group of records (`chunk`,
    /// [`FLAT_GROUP`] of them) shares for their ray-like lights, with the seconds they took:
    /// those of its representative record's receiver ([`flat_group_representative`]), when
    /// this kind of record draws flat and some record of the group gathers them. `None`
    /// otherwise.
    fn shared_flat_masses<R: Record>(
        &self,
        chunk: &[R],
        credits: &[Option<Component>],
    ) -> Option<(Vec<(u32, f32)>, f64)> {
        let sel = self
            .selection
            .filter(|sel| Drawing::of(R::FROM_RAYS.1, sel.media_drawing) == Drawing::Flat)?;
        let ts = self.ts;
        let gathered = chunk.iter().zip(credits).any(|(record, &credit)| {
            self.virtual_lights && record.gathers(ts) && self.computed[credited(R::FROM_RAYS.0, credit) as usize]
        });
        if !gathered || sel.vbls.is_empty() {
            return None;
        }
        let mut seconds = 0.0;
        let masses = timed(&mut seconds, || {
            let representative = &chunk[flat_group_representative(chunk.len())];
            sel.vbls.flat_masses(&representative.flat_receiver(&ts.scene), sel.r)
        });
        Some((masses, seconds))
    }

    /// Record `i`'s gather over one light set (the lights it draws with light selection,
    /// `rx`, or all of them), divided by the path count M, into the component it credits; the
    /// gather's time and discards are its own component's.
    fn gather<R: Record>(
        &self,
        e: &mut RecordEstimate,
        (i, record): (usize, &R),
        credit: Option<Component>,
        rx: Option<&(&Selection, Receiver)>,
        set: LightSet,
        flat: Option<&[(u32, f32)]>,
    ) {
        let (ts, inputs) = (self.ts, self.inputs);
        let est = Estimators {
            beams: self.beams,
            r2: inputs.radius2,
            vbl: &inputs.vbl,
            clamp: inputs.clamp,
        };
        let ((component, kind), lights) = match set {
            LightSet::Points => (R::FROM_POINTS, inputs.vpls.len()),
            LightSet::Rays => (R::FROM_RAYS, inputs.vrls.len()),
        };
        let drawn = rx.map(|(sel, rx)| {
            let tree = match set {
                LightSet::Points => &sel.vsls,
                LightSet::Rays => &sel.vbls,
            };
            let draw = match (flat, set) {
                (Some(masses), _) => Draw::Flat(masses),
                // VSLs drawn flat: by the record's own masses.
                (None, LightSet::Points) if sel.vsl_drawing == Drawing::Flat => Draw::Own,
                (None, _) => Draw::Descent,
            };
            (*sel, tree, rx, draw)
        });
        let own = component as usize;
        let v = gather_lights(
            drawn,
            (&mut e.seconds[own], &mut e.discarded[own]),
            lights,
            (kind, i, inputs.pair_seed, inputs.pass),
            &|j, s| match set {
                LightSet::Points => {
                    let walls = if self.beams { &inputs.vpl_walls[j] } else { &Walls::NONE };
                    record.point_light(ts, &inputs.vpls[j], walls, &est, s)
                }
                LightSet::Rays => record.ray_light(ts, &inputs.vrls[j], &est, s),
            },
        );
        e.add(
            credited(component, credit) as usize,
            injected(v / inputs.paths.max(1) as f32, self.poison(i, lights)),
        );
    }

    /// Fault injection (`inject_nan`): the gather over a set of `lights` poisons its first
    /// record, as the GPU's does.
    fn poison(&self, i: usize, lights: usize) -> bool {
        self.inputs.inject_nan && i == 0 && lights > 0
    }
}

/// What may enter an accumulator: `v` when it is finite and non-negative; otherwise it counts
/// in `discarded` and only its finite non-negative part passes (0 for NaN or ∞, negative
/// channels raised to 0). Every virtual-light, caustic and direct-light estimate goes through
/// this, once per drawn pair and once per record, on the CPU and (as `admit` in
/// `shaders/lib/gather.wgsl`) on the GPU.
#[inline]
pub fn admit(v: Rgb, discarded: &mut u64) -> Rgb {
    if v.is_finite() && v.min_element() >= 0.0 {
        return v;
    }
    *discarded += 1;
    if v.is_finite() { v.max(Rgb::ZERO) } else { Rgb::ZERO }
}

/// The component a record's estimate of `component` belongs to: itself at the camera's
/// records; the walk's credit at a walk record, whose (v1, v2) classify its every path
/// ([`beamlight_trace::components`]).
pub(crate) fn credited(component: Component, credit: Option<Component>) -> Component {
    credit.unwrap_or(component)
}

/// Direct light's random stream for record `i` of `kind` (0: shading points, 1: media
/// segments, walk segments numbered after the camera's) of a camera sample with `seed`.
pub(crate) fn direct_stream(seed: u32, pass: u32, kind: u32, i: usize) -> Sampler {
    Sampler::new(seed ^ 0x5bd1_e995, pass, (i as u32).wrapping_mul(2) + kind)
}

/// Fault injection ([`crate::many_lights::ManyLightSettings::inject_nan`]): `v`, or NaN when `poison`.
pub(crate) fn injected(v: Rgb, poison: bool) -> Rgb {
    if poison { Rgb::splat(f32::NAN) } else { v }
}

/// One pass's light trees and the lights each record draws from each.
pub(crate) struct Selection {
    pub(crate) k: u32,
    /// Draws per camera media segment from the VBL tree (`Lmm`,
    /// [`crate::many_lights::ManyLightSettings::media_light_samples`]).
    pub(crate) k_media: u32,
    /// How camera media segments draw VBLs (`Lmm`).
    pub(crate) media_drawing: Drawing,
    /// How records draw VSLs on the CPU (`Lss`, `Lms`): flat by each record's own masses.
    pub(crate) vsl_drawing: Drawing,
    /// The pass's VBL/VSL radius.
    pub(crate) r: f32,
    pub(crate) pair_seed: u32,
    pub(crate) pass: u32,
    pub(crate) vsls: LightTree,
    pub(crate) vbls: LightTree,
}

impl Selection {
    /// [`LightTree::estimate`] for record `record` of kind `kind` with its streams
    /// ([`streams`]: the selection number, each slot's descent and drawn pair), drawn as
    /// `draw` says, `f(light, stream)` the drawn light's contribution, each [`admit`]ted
    /// (counted in `discarded`); its CPU time added to `seconds` (an empty tree is not timed).
    #[allow(clippy::too_many_arguments)]
    fn timed_estimate(
        &self,
        seconds: &mut f64,
        discarded: &mut u64,
        (tree, draw): (&LightTree, Draw),
        rx: &Receiver,
        kind: GatherKind,
        record: usize,
        mut f: impl FnMut(usize, &mut Sampler) -> Rgb,
    ) -> Rgb {
        if tree.is_empty() {
            return Rgb::ZERO;
        }
        let (seed, pass, i) = (self.pair_seed, self.pass, record as u32);
        timed(seconds, || {
            tree.estimate(
                rx,
                self.r,
                if kind == GatherKind::VrlToMedia {
                    self.k_media
                } else {
                    self.k
                },
                streams::selection_number(seed, pass, kind, i),
                draw,
                |slot| streams::selection_sampler(seed, pass, kind, i, slot),
                |slot, j| {
                    admit(
                        f(j, &mut streams::drawn_pair_sampler(seed, pass, kind, i, slot)),
                        discarded,
                    )
                },
            )
        })
    }
}

/// One record's gather over a set of `lights` virtual lights, before the division by the path
/// count M: with light selection, the lights `drawn` from its tree for the record's receiver
/// (down the tree or by a flat draw's masses); without, every light, each with its pair's
/// stream. `f(index, stream)` is light `index`'s contribution; the gather's CPU time and
/// discards go to `(seconds, discarded)`; `(kind, record, pair_seed, pass)` name the record's
/// streams ([`streams`]).
pub(crate) fn gather_lights(
    drawn: Option<(&Selection, &LightTree, &Receiver, Draw)>,
    (seconds, discarded): (&mut f64, &mut u64),
    lights: usize,
    (kind, record, pair_seed, pass): (GatherKind, usize, u32, u32),
    f: &dyn Fn(usize, &mut Sampler) -> Rgb,
) -> Rgb {
    match drawn {
        Some((sel, tree, rx, draw)) => sel.timed_estimate(seconds, discarded, (tree, draw), rx, kind, record, f),
        None => timed_sum(seconds, discarded, lights, |j| {
            f(
                j,
                &mut streams::pair_sampler(pair_seed, pass, kind, record as u32, j as u32),
            )
        }),
    }
}

/// Σ over a light set of `lights` virtual lights of each one's contribution, `f(index)`, each
/// [`admit`]ted (counted in `discarded`); its CPU time added to `seconds` (an empty set costs
/// nothing and is not timed).
fn timed_sum(seconds: &mut f64, discarded: &mut u64, lights: usize, f: impl Fn(usize) -> Rgb) -> Rgb {
    if lights == 0 {
        return Rgb::ZERO;
    }
    timed(seconds, || (0..lights).map(|j| admit(f(j), discarded)).sum())
}

/// Runs `f`, adding its duration to `seconds` (per-component CPU time for `--stats`).
pub(crate) fn timed<R>(seconds: &mut f64, f: impl FnOnce() -> R) -> R {
    let clock = Instant::now();
    let r = f();
    *seconds += clock.elapsed().as_secs_f64();
    r
}
