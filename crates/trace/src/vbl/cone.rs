//! A virtual spherical light seen from a receiver: the cone of gather directions that pass
//! within R of its centre, the receiver's and the light's lobes over it, and the cone's
//! numerical integration with the beam radiance estimate's collection point (paper eq. 9 and
//! issue 19's correction, see the parent module).
use super::walls::{MAX_WALLS, Walls};
use crate::{TraceScene, camera_paths::ShadingPoint, light_paths::SurfaceVertex};
use beamlight_scene::{
    Rgb,
    bsdf::Bsdf,
    frame::Frame,
    medium::Medium,
    phase::HenyeyGreenstein,
    rng::Sampler,
    sampling::{self},
};
use glam::{Vec2, Vec3};

/// The cone of gather directions from a receiver whose rays pass within R of a VSL centre.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cone {
    pub(super) axis: Vec3,
    pub(super) cos: f32,
    pub(super) sin: f32,
    /// 1 − cos θmax, formed without cancellation.
    pub(super) one_minus_cos: f32,
    /// Ω / (πR²): the solid angle times the kernel (1/d² for R = 0).
    pub(super) weight: f32,
}

/// The VSL of squared radius `r2` centred at `centre`, seen from `from`; `fallback` is the
/// hemisphere's axis when the two points coincide. `None` when there is nothing to gather
/// (coincident points and R = 0).
pub(super) fn vsl_cone(from: Vec3, centre: Vec3, r2: f32, fallback: Vec3) -> Option<Cone> {
    let to = centre - from;
    let d2 = to.length_squared();
    let d = d2.sqrt();
    let axis = if d > 0.0 && (to / d).is_finite() {
        to / d
    } else {
        fallback
    };
    let cone = if d2 > r2 {
        // sin²θmax = R²/d²; 1 − cos = sin²/(1 + cos) keeps tiny cones exact.
        let sin2 = r2 / d2;
        let cos = ((d2 - r2) / d2).max(0.0).sqrt();
        Cone {
            axis,
            cos,
            sin: sin2.sqrt(),
            one_minus_cos: sin2 / (1.0 + cos),
            weight: 2.0 / (d2 * (1.0 + cos)),
        }
    } else {
        // Inside the sphere: the hemisphere facing the centre.
        Cone {
            axis,
            cos: 0.0,
            sin: 1.0,
            one_minus_cos: 1.0,
            weight: 2.0 / r2,
        }
    };
    (cone.weight.is_finite() && cone.weight > 0.0 && axis.is_finite()).then_some(cone)
}

/// The cone for a surface photon (a VPL) at `centre`: [`vsl_cone`] while the receiver lies
/// outside the sphere (every ray that crosses the surface within R of the photon passes within
/// R of it), and inside it the hemisphere about `inside`, the side the surface's disc lies on
/// (the VPL's surface seen from a medium point, or the receiver's own upper side): the hemisphere
/// facing the centre would miss part of the disc there.
pub(super) fn vsl_sheet_cone(from: Vec3, centre: Vec3, r2: f32, inside: Vec3) -> Option<Cone> {
    let mut cone = vsl_cone(from, centre, r2, inside)?;
    if (centre - from).length_squared() <= r2 {
        cone.axis = inside;
    }
    Some(cone)
}

/// The direction within `cone` closest to the unit direction `a`.
pub(super) fn closest_in_cone(cone: &Cone, a: Vec3) -> Vec3 {
    let ca = a.dot(cone.axis);
    if ca >= cone.cos {
        return a;
    }
    // Rotate the axis towards `a` by the cone's half-angle.
    let perp = a - cone.axis * ca;
    let len = perp.length();
    let perp = if len > 1e-6 {
        perp / len
    } else {
        // `a` opposite the axis: every rim direction is equally close.
        Frame::from_normal(cone.axis).s
    };
    (cone.axis * cone.cos + perp * cone.sin).normalize()
}

/// Angle (radians) over which a surface's f·cos changes appreciably: about 1/√n for a Phong
/// lobe of exponent n (cosⁿα ≈ exp(−nα²/2)), a radian for the cosine of a diffuse surface.
pub(super) fn bsdf_scale(b: &Bsdf) -> f32 {
    match *b {
        Bsdf::Phong { specular, exponent, .. } if specular.max_element() > 0.0 => (exponent + 1.0).sqrt().recip(),
        _ => 1.0,
    }
}

/// The same for a Henyey–Greenstein lobe: its forward peak has a half-width of about
/// (1 − |g|)/√|g| radians; (1 − |g|) is a little narrower, so the count below errs upwards.
pub(super) fn hg_scale(g: f32) -> f32 {
    (1.0 - g.abs()).max(1e-4)
}

/// Directions for integrating over `cone` an integrand that varies on the angular scale
/// `scale`: the share of `max` given by the cone's solid angle relative to the scale's, at
/// least 1. Any count gives an unbiased estimate of the cone integral; a cone much narrower
/// than the integrand's features sees a nearly constant integrand, so one direction has
/// almost no variance there, while a VSL that fills a lobe gets all `max` directions. This is
/// what keeps VSLs affordable: in most pairs the sphere is far away and its cone tiny.
pub(super) fn cone_directions(cone: &Cone, max: u32, scale: f32) -> u32 {
    // Half-angle² ≈ 2 (1 − cos θmax) for small cones (exact enough to choose a count).
    let ratio = 2.0 * cone.one_minus_cos / (scale * scale);
    let n = (max as f32 * ratio).ceil();
    if n >= max as f32 { max.max(1) } else { (n as u32).max(1) }
}

/// The integrand's sharpest factor as a distribution over gather directions ω', for drawing
/// some of a wide cone's directions from it (see [`integrate_cone`]).
#[derive(Clone, Copy, Debug)]
pub(super) enum Lobe {
    /// A surface's f·cos over gather directions (see [`Surface`]).
    Surface(Surface),
    /// A Henyey–Greenstein lobe hg.eval(`a`, `sign`·ω').
    Phase { hg: HenyeyGreenstein, a: Vec3, sign: f32 },
}

impl Lobe {
    pub(super) fn sample(&self, u: Vec2, u_pick: f32) -> Option<Vec3> {
        match *self {
            Lobe::Surface(sf) => {
                let bs = sf.bsdf.sample(sf.fixed, u, u_pick)?;
                (!bs.is_delta).then(|| sf.frame.to_world(bs.wi) * sf.sign)
            }
            Lobe::Phase { hg, a, sign } => Some(hg.sample(a, u).wi * sign),
        }
    }

    pub(super) fn pdf(&self, w: Vec3) -> f32 {
        match *self {
            Lobe::Surface(sf) => sf.bsdf.pdf(sf.fixed, sf.frame.to_local(w * sf.sign)),
            Lobe::Phase { hg, a, sign } => hg.pdf(a, w * sign),
        }
    }
}

/// The HG lobe hg.eval(a, sign·ω') over gather directions, with its angular scale.
pub(super) fn phase_lobe(hg: HenyeyGreenstein, a: Vec3, sign: f32) -> (Lobe, f32) {
    (Lobe::Phase { hg, a, sign }, hg_scale(hg.g))
}

/// Of two lobes, the one with the smaller angular scale.
pub(super) fn sharper(a: (Lobe, f32), b: (Lobe, f32)) -> (Lobe, f32) {
    if b.1 < a.1 { b } else { a }
}

/// Random numbers for [`integrate_cone`]: the shifts of the uniform and the lobe lattices and
/// the lobe-pick offset (five numbers, drawn whether or not they are used, so that a call
/// always consumes the same count).
#[derive(Clone, Copy, Debug)]
pub(super) struct ConeRandom {
    pub(super) uniform: Vec2,
    pub(super) lobe: Vec2,
    pub(super) pick: f32,
}

impl ConeRandom {
    pub(super) fn draw(s: &mut Sampler) -> Self {
        Self {
            uniform: s.next_2d(),
            lobe: s.next_2d(),
            pick: s.next_1d(),
        }
    }
}

/// (1/(πR²)) ∫_cone g(ω') dω', the VSL integral of eq. 9, estimated with directions uniform in
/// the cone (a shifted lattice) and, when the cone is wide compared with `lobe`'s angular
/// `scale`, half of them drawn from `lobe` instead, combined by the balance heuristic
/// (directions from the lobe that fall outside the cone count zero). Uniform directions alone
/// would find a glossy lobe inside a wide cone with probability its solid angle over the
/// cone's, which makes the rare hits the bright outliers of a pixel; narrow cones see nearly
/// constant integrands and get few uniform directions ([`cone_directions`]).
///
/// With a `disc` (a surface photon seen from beyond 2R, [`Collection::disc`]) the uniform
/// directions are replaced by directions towards uniform points of the photon's disc in its
/// surface, the only directions whose g is not 0 there: uniform ones would miss the disc (an
/// ellipse of |cos θ| times the cone's solid angle, θ the view's angle to the surface) and make
/// up for it with a 1/|cos θ| weight on the hits.
pub(super) fn integrate_cone(
    cone: &Cone,
    max: u32,
    lobe: Option<(Lobe, f32)>,
    disc: Option<SurfaceDisc>,
    rnd: ConeRandom,
    mut g: impl FnMut(Vec3) -> Rgb,
) -> Rgb {
    let omega = std::f32::consts::TAU * cone.one_minus_cos;
    let wide = lobe.filter(|&(_, scale)| 2.0 * cone.one_minus_cos >= scale * scale && omega > 0.0 && max >= 2);
    if let Some(disc) = disc {
        return integrate_disc(&disc, cone, max, lobe, wide.map(|(l, _)| l), rnd, g);
    }
    // The cone's own directions, from here on.
    let frame = Frame::from_normal(cone.axis);
    let Some((lobe, _)) = wide else {
        let n = cone_directions(cone, max, lobe.map_or(1.0, |(_, scale)| scale));
        let mut sum = Rgb::ZERO;
        for k in 0..n {
            let local = sampling::uniform_cone_1mc(sampling::shifted_lattice(k, n, rnd.uniform), cone.one_minus_cos);
            sum += g(frame.to_world(local).normalize());
        }
        return sum * (cone.weight / n as f32);
    };
    let (na, nb) = (max - max / 2, max / 2);
    // Balance heuristic over all na + nb directions: each counts g / (na p_uniform + nb p_lobe).
    let p_uniform = omega.recip();
    let denominator = |w: Vec3| na as f32 * p_uniform + nb as f32 * lobe.pdf(w);
    let mut sum = Rgb::ZERO;
    for k in 0..na {
        let local = sampling::uniform_cone_1mc(sampling::shifted_lattice(k, na, rnd.uniform), cone.one_minus_cos);
        let w = frame.to_world(local).normalize();
        sum += g(w) / denominator(w);
    }
    for k in 0..nb {
        let Some(w) = lobe_direction(&lobe, k, nb, rnd) else {
            continue;
        };
        if w.dot(cone.axis) >= cone.cos {
            sum += g(w) / denominator(w);
        }
    }
    // Ω / (πR²) over Ω: the kernel 1/(πR²).
    sum * (cone.weight / omega)
}

/// The k-th of n directions drawn from `lobe` (a shifted lattice, the BSDF's lobe picked by a
/// rotated offset).
fn lobe_direction(lobe: &Lobe, k: u32, n: u32, rnd: ConeRandom) -> Option<Vec3> {
    let pick = ((k as f32 + 0.5) / n as f32 + rnd.pick).fract();
    lobe.sample(sampling::shifted_lattice(k, n, rnd.lobe), pick)
}

/// [`integrate_cone`] for a surface photon's disc: the same count of directions, towards
/// uniform points of the disc (and from `wide`, the lobe, for half of them when the cone is
/// wide). Each counts g / (πR² p(ω')), p summed over the strategies by the balance heuristic;
/// a point drawn on the disc has πR² p = dist²/|cos θ| ([`SurfaceDisc::scaled_pdf`]), so the
/// weight of the disc's own directions is |cos θ|/dist², never above 1/R² beyond 2R.
fn integrate_disc(
    disc: &SurfaceDisc,
    cone: &Cone,
    max: u32,
    lobe: Option<(Lobe, f32)>,
    wide: Option<Lobe>,
    rnd: ConeRandom,
    mut g: impl FnMut(Vec3) -> Rgb,
) -> Rgb {
    let (na, nb) = match wide {
        Some(_) => (max - max / 2, max / 2),
        None => (cone_directions(cone, max, lobe.map_or(1.0, |(_, scale)| scale)), 0),
    };
    let area = std::f32::consts::PI * disc.r * disc.r;
    let mut term = |w: Vec3| {
        let q = disc.scaled_pdf(w);
        let lobe_share = wide.map_or(0.0, |l| nb as f32 * area * l.pdf(w));
        // A direction off the disc (a lobe's, or a disc point lost to rounding at its rim)
        // collects nothing: g is 0 there.
        if q > 0.0 {
            g(w) / (na as f32 * q + lobe_share)
        } else {
            Rgb::ZERO
        }
    };
    let mut sum = Rgb::ZERO;
    for k in 0..na {
        sum += term(disc.direction(sampling::shifted_lattice(k, na, rnd.uniform)));
    }
    if let Some(lobe) = wide {
        for k in 0..nb {
            if let Some(w) = lobe_direction(&lobe, k, nb, rnd) {
                sum += term(w);
            }
        }
    }
    sum
}

/// A surface photon's collection disc (radius `r` about `centre` in the surface whose normal
/// is `frame.n`) seen from `origin`, as a distribution of gather directions.
#[derive(Clone, Copy, Debug)]
pub(super) struct SurfaceDisc {
    pub(super) origin: Vec3,
    pub(super) centre: Vec3,
    pub(super) frame: Frame,
    pub(super) r: f32,
}

impl SurfaceDisc {
    /// The direction from the origin towards the disc point of `u` (concentric map).
    pub(super) fn direction(&self, u: Vec2) -> Vec3 {
        let p = sampling::concentric_disk(u) * self.r;
        let y = self.centre + self.frame.s * p.x + self.frame.t * p.y;
        (y - self.origin).normalize()
    }

    /// πR² times the density in solid angle of [`Self::direction`] for uniform u: dist²/|ω'·m|
    /// where the ray from the origin crosses the disc (dist the distance to the crossing), 0
    /// where it misses it. The test is [`Collection::on_surface`]'s, so that the two agree on
    /// every direction.
    pub(super) fn scaled_pdf(&self, w: Vec3) -> f32 {
        let to = self.centre - self.origin;
        let wm = w.dot(self.frame.n);
        let t = to.dot(self.frame.n) / wm;
        if !(t > 0.0) || !((w * t - to).length_squared() < self.r * self.r) {
            return 0.0;
        }
        t * t / wm.abs()
    }
}

/// Where along a gather ray a VSL's light is collected, and what that changes (issue 19). The
/// beam radiance estimate behind every VSL gathers, along a ray o + tω', the photons within R
/// of it: it integrates the photon density blurred over discs of radius R perpendicular to the
/// ray, each photon counted at the ray's point nearest to it. Two things follow that the VSL's
/// cone integral alone does not do, and whose neglect made the blur lose light at every R:
///
/// **Transmittance to the collection point.** The ray's light is attenuated up to where it is
/// collected: the ray's crossing with the photon's sheet (below) at t, not the VSL centre at
/// d = |centre − origin| ≥ t for a volume photon. The shadow ray to the centre gives T(d); the
/// ray's is T(d)^(t/d), exact in a homogeneous medium and, in a heterogeneous one, the
/// transmittance of the same mean extinction over the shorter distance (never above 1).
/// Without it, an infinite homogeneous medium lost about (σt R)²/2 of `Lmm` (6 % at σt R =
/// 0.35, by quadrature), and a receiver next to a lit wall (`Lms`) much more.
///
/// **Discs cut by a plane that hides the photons beyond it.** Where such a disc is cut, the
/// blurred density falls below the density; renormalising by the uncut fraction of the disc (the
/// boundary kernel of density estimation) makes the blur energy-preserving for a density that is
/// smooth across the disc. Away from the plane the fraction is 1, so the estimator is unchanged
/// there and converges as R → 0. For a volume VSL (a point of a VBL, `sheet` = `None`) the
/// disc faces ω' at the closest approach, and the receiver's tangent plane (`plane`, for
/// `Lsm`) cuts it: behind it nothing is visible from the receiver, so the discs near the start
/// of every oblique ray lose their part behind the surface. A medium receiver's discs at t > 0
/// are never cut by the receiver.
///
/// **A surface photon's disc lies in its surface.** A surface VSL (a VPL on the surface with
/// normal `sheet`) is collected where the ray crosses that surface, by the disc of radius R
/// around the crossing in the surface: the photon map's own kernel ([`Collection::on_surface`]).
/// The paper's disc facing the ray covers an ellipse on the surface stretched by 1/cos θ along
/// the view, so a wall seen at grazing angles was blurred over R/cos θ: by quadrature, for a
/// density ridge on a plane seen from 0.1 above it and 1–2 away, +2.5–3.4 % at R = 0.15 and
/// +10–12.5 % at R = 0.3 (now +0.3–0.7 % and +1.4–3.5 %); in the 5-deep glossy fog box the side
/// walls' `Lms` lost 1.3–1.8 % at R = 0.3. The surface disc needs no receiver cut (photons
/// within R of the crossing are the same whoever looks), and its weight is f, not f·cos: the
/// integrand carries the VPL's f·cos, so the weight divides by |cos θ|. Seen from beyond 2R,
/// its directions are drawn towards uniform points of the disc ([`Collection::disc`],
/// [`integrate_cone`]), which cancels that 1/|cos θ|. In `cornell_glossy_fog` (32², 300
/// passes, 16 seeds against `pt`) `Lms` went from −0.47 ± 0.21 % to −0.15 ± 0.21 %, at the
/// cost of 10 % more per-pixel variance in `Lms` and `Lss` (7 % in the image): a receiver at
/// height h over lit photons collects those below it with a weight that grows as ln(R/h).
///
/// Where the ray leaves the medium through a wall, the discs are cut too: a photon next to a
/// wall is collected by rays whose discs reach beyond it, where no photon can be. The photons
/// counted beyond the wall crossing (centre visibility) make up for it only where the
/// integrand is nearly linear across the disc, as a disc cut short before the crossing is
/// mirrored by one beyond it; next to the receiver the pairing breaks down (7.5 % of `Lmm` lost
/// 0.1 above the wall its segment ends on at R = 0.35, by quadrature), and at edges and corners
/// (the grey furnace cube lost 1.3 % at 2 R0, `Lss` and `Lms` 3–4 %). So every surface within
/// 2R of the photon ([`Walls`], found by probe rays from the VSL centre) is a further cut,
/// applied as a boundary kernel: nothing is collected beyond its plane, and a disc it cuts in
/// front of it is renormalised by its uncut fraction; exact at a plane wall, for any receiver.
/// For a volume VSL a wall that is the receiver's own surface is already its `plane`; a wall
/// the receiver lies behind is no boundary between the two (a surface that curves away): both
/// are skipped. Several cuts of one disc (walls at an edge or a corner, or a wall and the
/// receiver's plane) are renormalised by the exact fraction they leave together ([`Cuts`]).
///
/// **Where the photon scatters.** A VBL point's photon is collected at the gather ray's point
/// nearest to it, up to R away from the VRL: the blur estimates the beams' fluence there, so
/// the light scatters with the medium's density *at the collection point* ([`Collection::medium`]),
/// not at the VSL centre. With the centre's density the estimate would be the blur of
/// σ_s·fluence, which in a density grid spills the light of dense smoke into clear air next
/// to it, where nothing scatters it back (the smoke box's `Lmm` was 9 % low at 48², 200 passes);
/// with the collection point's, only the fluence is blurred. Both become the VRL estimate as
/// R → 0; in a homogeneous medium they are the same.
#[derive(Clone, Copy, Debug)]
pub(super) struct Collection<'a> {
    pub(super) origin: Vec3,
    pub(super) centre: Vec3,
    pub(super) plane: Option<Vec3>,
    pub(super) sheet: Option<Vec3>,
    pub(super) r: f32,
    /// Transmittance × visibility from `origin` to `centre` (the shadow ray's).
    pub(super) transmittance: Rgb,
    /// The surfaces next to the centre, where its photons' density ends.
    pub(super) walls: Walls,
    /// A VBL point's medium when it has a density grid: the light is scaled by the grid's
    /// density at the collection point (the caller leaves the density at the centre out).
    pub(super) medium: Option<&'a Medium>,
}

impl Collection<'_> {
    /// What the light gathered along `w` is multiplied by: the transmittance to the collection
    /// point over the uncut fraction of the disc, times the density there for a VBL point in a
    /// density grid (a surface photon: [`Self::on_surface`]).
    pub(super) fn weight(&self, w: Vec3) -> Rgb {
        if let Some(m) = self.sheet {
            return self.on_surface(w, m);
        }
        // A volume photon is collected at the gather ray's point nearest to it, t along the
        // ray, by a disc facing the ray.
        let to = self.centre - self.origin;
        let t = to.dot(w);
        let d = to.length();
        let share = if d > 0.0 { t.max(0.0) / d } else { 1.0 };
        let mut cuts = Cuts::default();
        // The receiver's tangent plane: the point's signed height t (ω'·n) above it, and the
        // disc's reach R |n − (ω'·n) ω'| across it.
        if let Some(n) = self.plane {
            let wn = w.dot(n);
            cuts.push(t * wn, self.r * (n - w * wn));
        }
        for wall in self.walls.planes() {
            let above = (self.origin - wall.point).dot(wall.normal);
            let own = self
                .plane
                .is_some_and(|n| n.dot(wall.normal) > 0.999 && above.abs() <= 1e-3 * self.r);
            if own || above < -1e-3 * self.r {
                continue;
            }
            // The collection point's height over the wall and the disc's reach across it.
            let wall_n = w.dot(wall.normal);
            if !cuts.push_wall(above + t * wall_n, self.r * (wall.normal - w * wall_n), self.r) {
                return Rgb::ZERO;
            }
        }
        let weight = cuts.weight(w);
        // Clamped into the grid's box: a point beyond a wall the probes did not find (one
        // tilted more than 30° off every axis) stands for the photons the centre's visibility
        // counts there in place of the cut discs (see above), which scatter in the medium next
        // to the wall.
        let density = self
            .medium
            .map_or(1.0, |m| m.density_near(self.origin + w * t.max(0.0)));
        transmittance_share(self.transmittance, share) * (weight * density)
    }

    /// The disc to draw gather directions from ([`integrate_cone`]): a surface photon's, seen
    /// from beyond 2R. Nearer, a ray towards a disc point would weigh up to 1/dist², unbounded
    /// as the receiver nears the surface, and the cone's directions are kept.
    pub(super) fn disc(&self) -> Option<SurfaceDisc> {
        let m = self.sheet?;
        let far = (self.centre - self.origin).length_squared() > 4.0 * self.r * self.r;
        (self.r > 0.0 && far).then(|| SurfaceDisc {
            origin: self.origin,
            centre: self.centre,
            frame: Frame::from_normal(m),
            r: self.r,
        })
    }

    /// [`Self::weight`] for a surface photon on the sheet with normal `m`: the ray collects it
    /// where it crosses the surface, within R of it (the photon map's disc in the surface).
    /// The integrand carries the VPL's f·cos and this kernel wants f, hence 1/|ω'·m|; the disc
    /// is cut by the walls next to the photon (the receiver's own surface included: photons
    /// end there too), and the light is attenuated to the crossing.
    fn on_surface(&self, w: Vec3, m: Vec3) -> Rgb {
        // R = 0: the cone is the direction to the photon alone, and the estimate the VPL's.
        if self.r == 0.0 {
            return self.transmittance;
        }
        let to = self.centre - self.origin;
        let wm = w.dot(m);
        let t = to.dot(m) / wm;
        // A ray that never reaches the surface, or crosses it more than R from the photon,
        // does not collect it (a NaN direction fails here as well and is counted upstream).
        if !(t > 0.0) || !((w * t - to).length_squared() < self.r * self.r) {
            return Rgb::ZERO;
        }
        let mut cuts = Cuts::default();
        for wall in self.walls.planes() {
            let above = (self.origin - wall.point).dot(wall.normal);
            if above < -1e-3 * self.r {
                continue;
            }
            // The crossing's height over the wall, and the disc's reach across the wall's
            // line in the surface.
            let height = above + t * w.dot(wall.normal);
            if !cuts.push_wall(height, self.r * (wall.normal - m * wall.normal.dot(m)), self.r) {
                return Rgb::ZERO;
            }
        }
        let d = to.length();
        transmittance_share(self.transmittance, t / d) * (cuts.weight(m) / wm.abs())
    }
}

/// T^share per channel (T ∈ [0, 1]; 0 stays 0, whatever the share). A NaN or negative T stays
/// NaN, for `many_lights::admit` to count.
#[inline]
pub(super) fn transmittance_share(tr: Rgb, share: f32) -> Rgb {
    let one = |t: f32| if t == 0.0 { 0.0 } else { (t.ln() * share).exp() };
    Rgb::new(one(tr.x), one(tr.y), one(tr.z))
}

/// The chords that cut one collection disc (the disc of radius R facing ω' at the collection
/// point, or a surface photon's disc in its surface): the receiver's and at most one per wall. Each is a half-plane of
/// the disc, given by `across`, the vector in the disc's plane towards the kept side whose
/// length is the disc's reach across the chord, and `height`, the centre's distance from the
/// chord on the kept side, both in the same units.
#[derive(Default)]
pub(super) struct Cuts {
    across: [Vec3; 1 + MAX_WALLS],
    height: [f32; 1 + MAX_WALLS],
    count: usize,
}

impl Cuts {
    /// Adds a chord if it meets the disc (a negative height, only met where the integrand is
    /// zero, e.g. a sheet crossing behind the receiver, is taken as 0).
    pub(super) fn push(&mut self, height: f32, across: Vec3) {
        let reach2 = across.length_squared();
        if !(reach2 > 0.0) || height * height >= reach2 && height >= 0.0 || self.count == self.across.len() {
            return;
        }
        self.across[self.count] = across;
        self.height[self.count] = height.max(0.0);
        self.count += 1;
    }

    /// Adds a wall's chord of a disc of radius `r`: `height` is the collection point's height
    /// over the wall, `across` the disc's reach across it. False where the point lies beyond
    /// the wall, where nothing is collected; a disc the wall misses, or one parallel to it
    /// (no reach across), is not cut.
    pub(super) fn push_wall(&mut self, height: f32, across: Vec3, r: f32) -> bool {
        let reach2 = across.length_squared();
        if (height >= 0.0 && height * height >= reach2) || !(reach2 > (1e-4 * r).powi(2)) {
            return true;
        }
        if height < 0.0 {
            return false;
        }
        self.push(height, across);
        true
    }

    /// 1 / (the fraction of the disc with normal `normal` that every chord leaves): 1 without chords, the closed
    /// form of a circular segment with one, and with more the disc clipped by their common
    /// polygon ([`kept_fraction`]). Exact for any number of chords: a product of one-chord
    /// fractions counts twice what two chords both remove (the receiver's and a wall's next to
    /// it: the blur gained 7 % for `Lms` 0.1 from a floor and a wall at R = 0.35) and removes
    /// too little where they cut opposite sides (a grazing ellipse reaching from the receiver
    /// to a wall: −1 %).
    pub(super) fn weight(&self, normal: Vec3) -> f32 {
        match self.count {
            0 => 1.0,
            1 => {
                let a = self.height[0] / self.across[0].length();
                let fraction = 0.5 + (a * (1.0 - a * a).sqrt() + a.asin()) * std::f32::consts::FRAC_1_PI;
                fraction.recip()
            }
            k => {
                // Coordinates in the disc's plane (every `across` lies in it), radius 1: the
                // first chord's direction and the normal × it.
                let e1 = self.across[0].normalize();
                let e2 = normal.cross(e1);
                let mut half_planes = [(Vec2::ZERO, 0.0); 1 + MAX_WALLS];
                for i in 0..k {
                    let (v, reach) = (self.across[i], self.across[i].length());
                    half_planes[i] = (Vec2::new(v.dot(e1), v.dot(e2)) / reach, self.height[i] / reach);
                }
                kept_fraction(&half_planes[..k]).recip()
            }
        }
    }
}

/// The fraction of the unit disc in the half-planes {v : v·u ≥ −a} (u a unit vector): the
/// square around the disc clipped by each (Sutherland–Hodgman; convex, so one pass each), then
/// the disc's area within the polygon as a sum of signed wedges over its edges.
pub(super) fn kept_fraction(half_planes: &[(Vec2, f32)]) -> f32 {
    // Each cut adds at most one corner to a convex polygon.
    const MOST: usize = 4 + 1 + MAX_WALLS;
    let mut polygon = [Vec2::ZERO; MOST];
    polygon[..4].copy_from_slice(&[Vec2::NEG_ONE, Vec2::new(1.0, -1.0), Vec2::ONE, Vec2::new(-1.0, 1.0)]);
    let mut count = 4;
    for &(u, a) in half_planes {
        let mut clipped = [Vec2::ZERO; MOST];
        let mut kept = 0;
        for i in 0..count {
            let (p, q) = (polygon[i], polygon[(i + 1) % count]);
            let (dp, dq) = (p.dot(u) + a, q.dot(u) + a);
            if dp >= 0.0 {
                clipped[kept] = p;
                kept += 1;
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                clipped[kept] = p + (q - p) * (dp / (dp - dq));
                kept += 1;
            }
        }
        (polygon, count) = (clipped, kept);
    }
    let area: f32 = (0..count)
        .map(|i| disc_wedge(polygon[i], polygon[(i + 1) % count]))
        .sum();
    area * std::f32::consts::FRAC_1_PI
}

/// The signed area of the unit disc within the triangle (0, a, b): the part of the edge inside
/// the circle spans a triangle, the parts outside a circular sector each.
fn disc_wedge(a: Vec2, b: Vec2) -> f32 {
    let sector = |p: Vec2, q: Vec2| 0.5 * p.perp_dot(q).atan2(p.dot(q));
    let d = b - a;
    // |a + s d|² = 1 ⟺ dd s² + 2 ad s + (aa − 1) = 0.
    let (dd, ad) = (d.dot(d), a.dot(d));
    let disc = ad * ad - dd * (a.dot(a) - 1.0);
    if !(dd > 0.0 && disc > 0.0) {
        return sector(a, b);
    }
    let root = disc.sqrt();
    let (s1, s2) = (((-ad - root) / dd).clamp(0.0, 1.0), ((-ad + root) / dd).clamp(0.0, 1.0));
    let (p1, p2) = (a + d * s1, a + d * s2);
    sector(a, p1) + 0.5 * p1.perp_dot(p2) + sector(p2, b)
}

/// A diffuse or glossy surface's f·cos as a function of the gather direction ω': at a camera
/// shading point ([`Surface::receiver`]) ω' is the incident direction and the fixed one is
/// towards the camera; at a VPL ([`Surface::light`]) the light leaves along −ω' and arrived
/// from the fixed direction. Lambert and modified Phong are reciprocal, so one evaluation
/// f(fixed, sign·ω') serves both, and sampling the BSDF about `fixed` samples either.
#[derive(Clone, Copy, Debug)]
pub(super) struct Surface {
    pub(super) bsdf: Bsdf,
    pub(super) frame: Frame,
    /// The fixed direction, local to `frame`.
    pub(super) fixed: Vec3,
    pub(super) n: Vec3,
    /// +1 at a receiver, −1 at a VPL: the surface's direction is `sign`·ω'.
    pub(super) sign: f32,
    /// The gather direction where f·cos peaks (the lobe's axis), for ω'_max.
    pub(super) peak: Vec3,
}

impl Surface {
    pub(super) fn new(ts: &TraceScene, material: u32, uv: Vec2, n: Vec3, fixed: Vec3, sign: f32) -> Option<Self> {
        let bsdf = ts.scene.bsdf_at(material, Some(uv))?;
        if bsdf.is_delta() {
            return None;
        }
        let frame = Frame::from_normal(n);
        Some(Self {
            bsdf,
            frame,
            fixed: frame.to_local(fixed),
            n,
            sign,
            peak: surface_peak(&bsdf, n, fixed) * sign,
        })
    }

    pub(super) fn receiver(ts: &TraceScene, sp: &ShadingPoint) -> Option<Self> {
        let n = Vec3::from(sp.normal);
        Self::new(ts, sp.material, Vec2::from(sp.uv), n, Vec3::from(sp.wo), 1.0)
    }

    pub(super) fn light(ts: &TraceScene, vpl: &SurfaceVertex) -> Option<Self> {
        let (n, uv) = (Vec3::from(vpl.normal), Vec2::new(vpl.u, vpl.v));
        Self::new(ts, vpl.material, uv, n, Vec3::from(vpl.wi), -1.0)
    }

    #[inline]
    pub(super) fn f_cos(&self, w: Vec3) -> Rgb {
        let x = self.frame.to_local(w * self.sign);
        self.bsdf.eval(self.fixed, x) * x.z.abs()
    }

    /// ω'_max within `cone`: the gather direction closest to the lobe's peak (the mirror
    /// direction of the fixed one for Phong, the normal for Lambert), or closest to the normal
    /// if that one lies below the horizon.
    pub(super) fn max_dir(&self, cone: &Cone) -> Vec3 {
        surface_max_dir(cone, self.peak, self.n * self.sign)
    }

    /// f·cos over gather directions as a lobe to draw directions from, with its angular scale.
    pub(super) fn lobe(&self) -> (Lobe, f32) {
        (Lobe::Surface(*self), bsdf_scale(&self.bsdf))
    }
}

/// Where a scattering function at a surface peaks, as an outgoing direction on the side of
/// `n`: the mirror direction of `fixed` for Phong (with a specular part), the normal otherwise.
pub(super) fn surface_peak(bsdf: &Bsdf, n: Vec3, fixed: Vec3) -> Vec3 {
    match bsdf {
        Bsdf::Phong { specular, .. } if specular.max_element() > 0.0 => {
            let r = n * (2.0 * n.dot(fixed)) - fixed;
            r.try_normalize().unwrap_or(n)
        }
        _ => n,
    }
}

/// ω'_max for a surface receiver (or, mirrored, a surface VSL): the direction in the cone
/// closest to `peak`, or closest to the normal `n` if that one is below the horizon.
pub(super) fn surface_max_dir(cone: &Cone, peak: Vec3, n: Vec3) -> Vec3 {
    let w = closest_in_cone(cone, peak);
    if w.dot(n) > 0.0 { w } else { closest_in_cone(cone, n) }
}
