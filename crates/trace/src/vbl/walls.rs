//! The surfaces next to a VSL centre, found by short probe rays: where its photons' density ends,
//! so that the blur around it can be cut there as a boundary kernel ([`super::cone::Collection`]).
//!
//! A photon near a wall is collected by gather rays whose discs of radius R reach beyond the
//! wall, where no photon can be: each such disc sees too few photons and the blur loses light.
//! Renormalising a disc by its part in front of the wall, and collecting nothing beyond the
//! wall, is exact for a plane wall and a density that is smooth across the disc, whatever the
//! receiver (issue 35: in the grey furnace cube the blur lost 1.3 % at 2 R0, mostly from discs
//! cut by walls next to the photons rather than by the receiver's own surface).
//!
//! The walls are found from the photon's side: a collection point lies within R of a volume
//! photon, so a disc there is cut only by a surface within 2R of the photon. Six probes along
//! the world axes (scenes built by people are mostly aligned with them) of length 2R / cos 30°
//! look for them; a surface counts when a probe meets it within 30° of head-on (an oblique hit
//! on a curved surface would give a tangent plane that cuts into the free space beside it) and
//! its plane passes within 2R of the centre (a surface closer than R/1000 along the probe,
//! which a beam's ends lie on by rounding on either side, is passed over). A surface VSL (a
//! VPL) probes along its own surface only: a plane parallel to its surface cannot cut its
//! ellipse. Surfaces without a BSDF (invisible medium boundaries) are not walls: light and
//! photons pass them.
//!
//! A plane is only a model of the surface where the surface is there: past the edge of a
//! finite face the space is free again. So a probe's surface counts only if its planar patch
//! ([`crate::patches::Patches`]: the triangles joined across shared edges in one plane) covers
//! every point of its plane within 2R of the centre, i.e. no open edge of the patch lies that
//! close to the probe's hit. Which edges are open depends on the side the probe comes from: a
//! room's corner seen from inside ends nothing, a box's edge seen from outside does, however
//! the surfaces are wound. Without this, next to the convex edges of a box every disc
//! reaching past the edge was renormalised as if the face went on (light counted twice in
//! front of the plane) and nothing was collected beside the box behind it: in the smoke box,
//! whose plume rises past the tall block's edge, `Lmm` came out 2–4 % high along the plume
//! (December 2026, 96², 64 s, three seeds against a 300-s `pt --only Lmm`). A ball's faces
//! are small patches with open edges all round, so it is a wall only once 2R fits inside one,
//! where its plane is a fair model. A probe that meets a plate too small to be a wall (a
//! lamp's quad under the ceiling) goes on to the next surface, once. A VPL's walls (a surface
//! VSL's) keep the infinite planes: at a block's foot they were measured better
//! ([`Candidate::covered`]).
use crate::{
    TraceScene,
    bvh::Hit,
    patches::{BACK, FRONT},
};
use glam::Vec3;

/// The probes' directions, and the most walls a centre keeps (one per probe).
const AXES: [Vec3; 6] = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];
pub const MAX_WALLS: usize = AXES.len();
/// cos 30°: how nearly head-on a probe must meet a surface for its plane to be a wall.
const HEAD_ON: f32 = 0.866_025_4;

/// A wall's plane: a point of it and its unit normal, facing the VSL centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    pub normal: Vec3,
}

/// The walls near one VSL centre (at most [`MAX_WALLS`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Walls {
    planes: [Plane; MAX_WALLS],
    count: usize,
}

impl Walls {
    /// No walls: the blur is cut by the receiver's plane alone.
    pub const NONE: Walls = Walls {
        planes: [Plane {
            point: Vec3::ZERO,
            normal: Vec3::ZERO,
        }; MAX_WALLS],
        count: 0,
    };

    /// The walls given (the first [`MAX_WALLS`]); for tests and callers that know them.
    pub fn of(planes: &[Plane]) -> Self {
        let mut walls = Self::NONE;
        for &p in planes.iter().take(MAX_WALLS) {
            walls.planes[walls.count] = p;
            walls.count += 1;
        }
        walls
    }

    pub fn planes(&self) -> &[Plane] {
        &self.planes[..self.count]
    }

    /// The walls within 2R of `centre`, probed from `from` (the centre itself in a medium; for
    /// a VPL, a point just off its surface, whose normal is `sheet`).
    pub fn around(ts: &TraceScene, centre: Vec3, from: Vec3, r: f32, sheet: Option<Vec3>) -> Self {
        let mut walls = Self::NONE;
        let reach = 2.0 * r;
        if !(reach > 0.0 && reach.is_finite()) {
            return walls;
        }
        for d in AXES {
            if sheet.is_some_and(|n| d.dot(n).abs() > 0.5) {
                continue;
            }
            // A surface the probe starts on (a beam's first or last point lies on one, on
            // either side by rounding) says nothing reliable about which side is free.
            let Some(hit) = ts.bvh.closest_hit(from, d, reach / HEAD_ON).filter(|h| h.t > 1e-3 * r) else {
                continue;
            };
            let wall = match candidate(ts, centre, from, d, r, sheet, &hit) {
                Some(c) if c.covered(ts, sheet) => c,
                // A plate too small to be a plane here (a lamp's quad under a ceiling): the
                // probe goes on to the next surface, once.
                Some(c) if ts.patches.is_plate(c.tri, c.side) => {
                    match ts
                        .bvh
                        .closest_hit_beyond(from, d, hit.t, reach / HEAD_ON)
                        .and_then(|next| candidate(ts, centre, from, d, r, sheet, &next))
                    {
                        Some(c) if c.covered(ts, sheet) => c,
                        _ => continue,
                    }
                }
                _ => continue,
            };
            let plane = wall.plane;
            // The same wall met by a second probe.
            let known = walls.planes().iter().any(|p| {
                p.normal.dot(plane.normal) > 0.999 && (plane.point - p.point).dot(plane.normal).abs() <= 1e-3 * r
            });
            if !known {
                walls.planes[walls.count] = plane;
                walls.count += 1;
            }
        }
        walls
    }
}

/// A surface that a probe met head-on with its plane within 2R of the centre: a wall if its
/// planar patch covers that plane there.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    /// The plane, facing the centre.
    plane: Plane,
    tri: u32,
    /// The side of the triangle the probe came from ([`FRONT`] or [`BACK`]).
    side: u8,
    /// How far around the hit the patch must reach: √((2R)² − h²) + the foot's distance.
    need: f32,
}

impl Candidate {
    /// Whether it is a wall: for a volume VSL centre, where its planar patch covers the plane
    /// within 2R; for a VPL (its surface's normal `sheet`), always, as an infinite plane.
    ///
    /// Neither rule is exact at a convex edge, and each kind of light keeps the one measured
    /// better for it. Volume photons beside a solid's edge (the smoke box's plume past the
    /// tall block) were 2–4 % too bright with infinite planes and within 2 % with patches;
    /// VPLs on the floor at a block's foot, whose probes meet the block's face, left the
    /// Cornell box 3–5 % too dark there with patches (the face's side edges and its bottom
    /// edge, a fold of the block meeting the floor in no shared edge, lie within 2R), and
    /// `vbl` at 64 s (96², seed 0) had relMSE 1.63e-4 against 1.07e-4 with infinite planes.
    fn covered(&self, ts: &TraceScene, sheet: Option<Vec3>) -> bool {
        sheet.is_some()
            || ts
                .patches
                .covers(&ts.scene, self.tri, self.side, self.plane.point, self.need)
    }
}

/// The candidate wall, if any, that `hit` of the probe from `from` along `d` gives the centre.
fn candidate(
    ts: &TraceScene,
    centre: Vec3,
    from: Vec3,
    d: Vec3,
    r: f32,
    sheet: Option<Vec3>,
    hit: &Hit,
) -> Option<Candidate> {
    let reach = 2.0 * r;
    let tri = &ts.scene.triangles[hit.tri as usize];
    // Invisible medium boundaries (no BSDF) are no walls.
    ts.scene.materials[tri.material as usize].bsdf.as_ref()?;
    let ng = tri.cross().normalize_or_zero();
    // The side of the surface the probe comes from, which decides its open edges.
    let (normal, side) = if ng.dot(d) > 0.0 { (-ng, BACK) } else { (ng, FRONT) };
    if -d.dot(normal) < HEAD_ON || sheet.is_some_and(|n| normal.dot(n).abs() > 0.99) {
        return None;
    }
    let point = from + d * hit.t;
    let height = (centre - point).dot(normal);
    if !(height <= reach) {
        return None;
    }
    // The plane within 2R of the centre is a disc of radius √((2R)² − h²) around the centre's
    // foot on it; it lies inside the patch when the patch has no open edge within that radius
    // plus the foot's distance from the hit.
    let foot = centre - normal * height;
    let need = (reach * reach - height * height).max(0.0).sqrt() + point.distance(foot);
    Some(Candidate {
        plane: Plane { point, normal },
        tri: hit.tri,
        side,
        need,
    })
}
