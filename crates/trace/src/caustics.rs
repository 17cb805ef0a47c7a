//! Caustics: light that reaches the first diffuse/glossy camera vertex through a specular
//! bounce, which no straight connection to a virtual light can carry (see `components`).
//!
//! * `caustic_surface` — progressive photon mapping (Hachisuka et al. 2008) in Knaus and
//!   Zwicker's (2011) probabilistic form: every pass is an independent photon-map density
//!   estimate with its own radius, and the running average of the passes converges because the
//!   radius shrinks by the schedule of the paper's eq. 11. The kernel is the constant disc
//!   kernel 1/(πr²) over photons within distance r.
//! * `caustic_volume` — progressive photon beams (Jarosz et al. 2011), beam × camera-ray
//!   estimate with a 2-D blur: each beam is widened into a tube of radius r whose cross-section
//!   carries the constant kernel 1/(πr²), and the camera ray is integrated through the tube
//!   analytically (the length of the chord it cuts), with the slowly varying terms (σs, phase,
//!   both transmittances) taken at the chord's midpoint. As r → 0 the chord over πr² becomes
//!   the delta function of the beam integrated along the ray, 1/sin θ per unit of the
//!   beam–ray distance: the unblurred beam–ray transport. The same squared-radius schedule
//!   applies (the blur is 2-D, as the paper's §4.1 says of its beams).
//!
//! Both gathers return radiance per light path traced, like the VRL/VPL ones: divide a set's
//! sum by its path count. Photons and beams are found through a [`BoxTree`] built per pass.
use crate::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    light_paths::{AFTER_SPECULAR, LightSegment, SurfaceVertex},
    media,
    spatial::BoxTree,
};
use beamlight_scene::{Rgb, frame::Frame, phase::HenyeyGreenstein, rng::Sampler};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Surface caustic photons of one pass, indexed for radius queries.
pub struct PhotonMap<'a> {
    photons: &'a [SurfaceVertex],
    tree: BoxTree,
    r2: f32,
}

impl<'a> PhotonMap<'a> {
    /// Indexes `photons` for gathers of squared radius `r2`.
    pub fn build(photons: &'a [SurfaceVertex], r2: f32) -> Self {
        let r = r2.sqrt();
        let boxes: Vec<(Vec3, Vec3)> = photons
            .iter()
            .map(|p| (Vec3::from(p.pos) - r, Vec3::from(p.pos) + r))
            .collect();
        Self {
            photons,
            tree: BoxTree::build(&boxes),
            r2,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }

    /// Reflected caustic radiance at `sp` towards its pixel, per light path:
    /// Σ f(wo, wi_p) Φ_p / (πr²) over photons within r on the same side of the surface.
    pub fn radiance(&self, ts: &TraceScene, sp: &ShadingPoint) -> Rgb {
        if self.tree.is_empty() || !(self.r2 > 0.0) {
            return Rgb::ZERO;
        }
        let Some(bsdf) = ts.scene.bsdf_at(sp.material, Some(Vec2::from(sp.uv))) else {
            return Rgb::ZERO;
        };
        let (x, n) = (Vec3::from(sp.pos), Vec3::from(sp.normal));
        let frame = Frame::from_normal(n);
        let wo = frame.to_local(Vec3::from(sp.wo));
        let mut sum = Rgb::ZERO;
        self.tree.for_each_containing(x, |i| {
            let p = &self.photons[i as usize];
            // Photons on the other side of a thin wall, or on a surface facing away, carry
            // light this point cannot receive.
            if (Vec3::from(p.pos) - x).length_squared() >= self.r2 || Vec3::from(p.normal).dot(n) <= 0.0 {
                return;
            }
            sum += bsdf.eval(wo, frame.to_local(Vec3::from(p.wi))) * Rgb::from(p.power);
        });
        // Not cleaned: the caller counts what it must discard (`many_lights::admit`).
        Rgb::from(sp.throughput) * sum / (PI * self.r2)
    }
}

/// The photon beams of one pass that carry volume caustics (those leaving a specular bounce),
/// indexed for camera-ray queries. The tree holds pieces of the beams, not whole beams: a
/// long oblique beam's box is mostly empty space, and every camera segment through it would
/// test the beam. With pieces at most 1/[`PIECES_PER_EXTENT`] of the beams' extent long, a
/// segment tests only the pieces near it (CARS' small twin at 320×180 with 32 768 beam paths
/// a pass: `caustic_volume` 25.5 CPU-s over 3 passes as whole beams).
pub struct BeamMap {
    beams: Vec<LightSegment>,
    /// Per piece: its beam and its stretch [u0, u1] of the beam's parameter.
    pieces: Vec<(u32, f32, f32)>,
    tree: BoxTree,
    r2: f32,
}

/// Beams are cut into pieces no longer than the diagonal of all beams' bounds over this.
pub const PIECES_PER_EXTENT: f32 = 32.0;

impl BeamMap {
    /// Keeps the beams of `beams` that start right after a specular bounce (single scattering
    /// straight from the lights is direct light, estimated by next-event estimation instead).
    pub fn build(beams: &[LightSegment], r2: f32) -> Self {
        let beams: Vec<LightSegment> = beams
            .iter()
            .filter(|b| b.flags & AFTER_SPECULAR != 0 && b.length > 0.0)
            .copied()
            .collect();
        let r = r2.sqrt();
        let ends = |b: &LightSegment| {
            let o = Vec3::from(b.origin);
            (o, o + Vec3::from(b.dir) * b.length)
        };
        let (lo, hi) = beams.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), b| {
            let (a, e) = ends(b);
            (lo.min(a).min(e), hi.max(a).max(e))
        });
        let piece = ((hi - lo).length() / PIECES_PER_EXTENT).max(r);
        let mut pieces = Vec::new();
        let mut boxes = Vec::new();
        for (i, b) in beams.iter().enumerate() {
            let n = (b.length / piece).ceil().clamp(1.0, 1024.0) as u32;
            let (o, d) = (Vec3::from(b.origin), Vec3::from(b.dir));
            for k in 0..n {
                let u0 = b.length * k as f32 / n as f32;
                let u1 = if k + 1 == n {
                    b.length
                } else {
                    b.length * (k + 1) as f32 / n as f32
                };
                let (a, e) = (o + d * u0, o + d * u1);
                pieces.push((i as u32, u0, u1));
                boxes.push((a.min(e) - r, a.max(e) + r));
            }
        }
        Self {
            tree: BoxTree::build(&boxes),
            beams,
            pieces,
            r2,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }

    /// Radiance the beams scatter into a camera media segment towards its pixel, per light
    /// path: Σ Φ T_beam σs f_HG T_cam · chord / (πr²).
    pub fn radiance(&self, ts: &TraceScene, seg: &MediaSegment, s: &mut Sampler) -> Rgb {
        if self.tree.is_empty() || !(self.r2 > 0.0) {
            return Rgb::ZERO;
        }
        let m = &ts.scene.media[seg.medium as usize];
        let hg = HenyeyGreenstein { g: m.g };
        let (oc, dc) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
        let mut sum = Rgb::ZERO;
        self.tree.for_each_on_segment(oc, dc, seg.length, |i| {
            let (beam, u0, u1) = self.pieces[i as usize];
            let b = &self.beams[beam as usize];
            if b.medium != seg.medium {
                return;
            }
            // The piece's part of the tube: the beam's tube is the union of its pieces' (cut
            // across the beam where one ends), so their chords add up to the beam's.
            let (ob, db) = (Vec3::from(b.origin), Vec3::from(b.dir));
            let Some((t0, t1)) = chord(oc, dc, seg.length, ob + db * u0, db, u1 - u0, self.r2) else {
                return;
            };
            let t = 0.5 * (t0 + t1);
            let x = oc + dc * t;
            let u = (x - ob).dot(db).clamp(u0, u1);
            let sigma_s = m.sigma_s * m.density_at(x);
            let phase = hg.eval(-dc, -db);
            let t_beam = media::transmittance(m, ob, db, u, s);
            let t_cam = media::transmittance(m, oc, dc, t, s);
            sum += Rgb::from(b.power) * t_beam * sigma_s * t_cam * (phase * (t1 - t0));
        });
        Rgb::from(seg.throughput) * sum / (PI * self.r2)
    }
}

/// The part `[t0, t1]` of the camera segment `oc + t·dc`, `t ∈ [0, lc]`, inside the tube of
/// squared radius `r2` around the beam `ob + u·db`, `u ∈ [0, lb]` (a cylinder without caps:
/// points within distance r of the beam's line whose projection falls on the beam).
pub fn chord(oc: Vec3, dc: Vec3, lc: f32, ob: Vec3, db: Vec3, lb: f32, r2: f32) -> Option<(f32, f32)> {
    let w = oc - ob;
    // Distance² to the beam's line along the ray: |p + t q|², p and q the parts of w and dc
    // perpendicular to the beam.
    let (p, q) = (w - db * w.dot(db), dc - db * dc.dot(db));
    let qq = q.length_squared();
    let (mut t0, mut t1) = (0.0f32, lc);
    if qq > 1e-12 {
        let t_star = -p.dot(q) / qq;
        let h2 = (p + q * t_star).length_squared();
        if h2 >= r2 {
            return None;
        }
        let half = ((r2 - h2) / qq).sqrt();
        t0 = t0.max(t_star - half);
        t1 = t1.min(t_star + half);
    } else if p.length_squared() >= r2 {
        // Parallel to the beam and outside the tube.
        return None;
    }
    // Projection onto the beam, a + c·t, must stay within [0, lb].
    let (a, c) = (w.dot(db), dc.dot(db));
    if c.abs() > 1e-6 {
        let (u0, u1) = ((0.0 - a) / c, (lb - a) / c);
        t0 = t0.max(u0.min(u1));
        t1 = t1.min(u0.max(u1));
    } else if !(0.0..=lb).contains(&a) {
        return None;
    }
    (t1 > t0 && t0.is_finite() && t1.is_finite()).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray crossing a beam at right angles at distance h cuts a chord 2√(r² − h²).
    #[test]
    fn perpendicular_chord_has_the_circle_length() {
        let (r, h) = (0.2f32, 0.12f32);
        let oc = Vec3::new(0.0, h, -5.0);
        let (t0, t1) = chord(oc, Vec3::Z, 10.0, Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 2.0, r * r).unwrap();
        assert!(((t1 - t0) - 2.0 * (r * r - h * h).sqrt()).abs() < 1e-5);
        assert!((0.5 * (t0 + t1) - 5.0).abs() < 1e-5);
        assert!(chord(oc, Vec3::Z, 10.0, Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 0.5, r * r).is_none());
        assert!(chord(oc, Vec3::Z, 4.0, Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 2.0, r * r).is_none());
    }

    /// At angle θ the chord is 2√(r² − h²)/sin θ; integrated over the offset h it gives
    /// πr²/sin θ, so chord/(πr²) is a unit kernel in the beam–ray distance, over 1/sin θ.
    #[test]
    fn oblique_chord_integrates_to_the_kernel_normalization() {
        let r = 0.1f32;
        let theta = 0.5f32;
        let dc = Vec3::new(theta.cos(), 0.0, theta.sin());
        let n = 2000;
        let mut integral = 0.0f64;
        for k in 0..n {
            let h = -r + 2.0 * r * (k as f32 + 0.5) / n as f32;
            let oc = Vec3::new(0.0, h, 0.0) - dc * 5.0;
            if let Some((t0, t1)) = chord(oc, dc, 10.0, Vec3::new(-5.0, 0.0, 0.0), Vec3::X, 10.0, r * r) {
                integral += (t1 - t0) as f64 * (2.0 * r / n as f32) as f64;
            }
        }
        let expected = (PI * r * r / theta.sin()) as f64;
        assert!((integral / expected - 1.0).abs() < 1e-3, "{integral} vs {expected}");
    }

    /// A ray running along the beam inside the tube gets the overlap of the two; outside, none.
    #[test]
    fn parallel_rays_are_finite() {
        let (t0, t1) = chord(
            Vec3::new(0.0, 0.05, 0.0),
            Vec3::X,
            3.0,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::X,
            1.0,
            0.01,
        )
        .unwrap();
        assert!((t0 - 1.0).abs() < 1e-6 && (t1 - 2.0).abs() < 1e-6);
        assert!(chord(Vec3::new(0.0, 0.2, 0.0), Vec3::X, 3.0, Vec3::ZERO, Vec3::X, 1.0, 0.01).is_none());
        assert!(chord(Vec3::ZERO, Vec3::X, 3.0, Vec3::ZERO, Vec3::X, 0.0, 0.01).is_none());
    }
}
