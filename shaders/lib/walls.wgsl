//! use lib/bvh.wgsl
//! use lib/sampling.wgsl
// The walls next to a VSL centre, twins of `beamlight_trace::vbl::walls`: where its photons'
// density ends, found by short probe rays, so that the blur can be cut there.

// `vbl::Plane`: a wall's plane, a point of it and its unit normal facing the VSL centre.
struct Plane {
    point: vec3<f32>,
    _pad0: u32,
    normal: vec3<f32>,
    _pad1: u32,
}

// `vbl::Walls`: the walls next to a VSL centre (at most MAX_WALLS, one per probe).
const MAX_WALLS: u32 = 6u;
struct Walls {
    planes: array<Plane, 6>,
    count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// cos 30°: how nearly head-on a probe must meet a surface for its plane to be a wall.
const HEAD_ON: f32 = 0.8660254;

// Probe direction k of `walls::AXES`: +x, −x, +y, −y, +z, −z.
fn probe_axis(k: u32) -> vec3<f32> {
    let s = select(-1.0, 1.0, k % 2u == 0u);
    return vec3<f32>(select(0.0, s, k / 2u == 0u), select(0.0, s, k / 2u == 1u), select(0.0, s, k / 2u == 2u));
}

// What a probe's hit says about the free space around a centre (`walls::Probed`).
const PROBED_NONE: u32 = 0u;
const PROBED_WALL: u32 = 1u;
const PROBED_PAST: u32 = 2u;
struct Probed {
    kind: u32,
    plane: Plane,
}

// `walls::probed` for a volume VSL centre probed from itself along axis `k`.
fn probed(centre: vec3<f32>, r: f32, k: u32, hit: Hit) -> Probed {
    var out: Probed;
    out.kind = PROBED_NONE;
    let reach = 2.0 * r;
    if (triangle_info[hit.tri].flags & TRI_NULL_INTERFACE) != 0u {
        return out;
    }
    let d = probe_axis(k);
    let t = scene_triangle(hit.tri);
    let ng = normalize_or_zero(cross(t.p1 - t.p0, t.p2 - t.p0));
    // The side of the surface the probe comes from, which decides its open edges.
    let back = dot(ng, d) > 0.0;
    let normal = select(ng, -ng, back);
    let side = select(SIDE_FRONT, SIDE_BACK, back);
    let point = centre + d * hit.t;
    let height = dot(centre - point, normal);
    if -dot(d, normal) < HEAD_ON || !(height <= reach) {
        return out;
    }
    // The plane within 2R of the centre must lie inside the triangle's planar patch.
    let foot = centre - normal * height;
    let need = sqrt(max(reach * reach - height * height, 0.0)) + distance(point, foot);
    let plate = (triangle_info[hit.tri].flags & select(TRI_PLATE_FRONT, TRI_PLATE_BACK, back)) != 0u;
    out.kind = select(select(PROBED_NONE, PROBED_PAST, plate), PROBED_WALL, patch_covers(hit.tri, t, side, point, need));
    out.plane = Plane(point, 0u, normal, 0u);
    return out;
}

// `Walls::around` for a volume VSL centre (probed from the centre itself; a VPL's walls are
// found on the CPU, `vpl_walls`): the surfaces with a BSDF that a probe along an axis meets
// within 30° of head-on, whose plane passes within 2R of `centre` and whose planar patch
// covers it there; a probe goes past a plate that ends within 2R to the next surface, once
// (a second traversal, only when some probe needs it).
fn walls_around(centre: vec3<f32>, r: f32) -> Walls {
    var walls: Walls;
    let reach = 2.0 * r;
    if !(reach > 0.0 && finite_f32(reach)) {
        return walls;
    }
    let tmax = reach / HEAD_ON;
    let first = probe_hits(centre, array<f32, 6>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), tmax);
    var found: array<Probed, 6>;
    // Where each probe goes on from; a negative start stops it.
    var beyond = array<f32, 6>(-1.0, -1.0, -1.0, -1.0, -1.0, -1.0);
    var again = false;
    for (var k = 0u; k < MAX_WALLS; k++) {
        let hit = first[k];
        // A surface the probe starts on says nothing reliable about which side is free.
        if !(hit.t > 1e-3 * r) {
            found[k].kind = PROBED_NONE;
            continue;
        }
        found[k] = probed(centre, r, k, hit);
        if found[k].kind == PROBED_PAST {
            beyond[k] = hit.t;
            again = true;
        }
    }
    if again {
        let next = probe_hits(centre, beyond, tmax);
        for (var k = 0u; k < MAX_WALLS; k++) {
            if beyond[k] >= 0.0 {
                if next[k].t >= 0.0 {
                    let p = probed(centre, r, k, next[k]);
                    if p.kind == PROBED_WALL {
                        found[k] = p;
                    }
                }
            }
        }
    }
    for (var k = 0u; k < MAX_WALLS; k++) {
        if found[k].kind != PROBED_WALL {
            continue;
        }
        let point = found[k].plane.point;
        let normal = found[k].plane.normal;
        // The same wall met by a second probe.
        var known = false;
        for (var i = 0u; i < walls.count; i++) {
            let p = walls.planes[i];
            known = known || (dot(p.normal, normal) > 0.999 && abs(dot(point - p.point, normal)) <= 1e-3 * r);
        }
        if !known {
            walls.planes[walls.count] = found[k].plane;
            walls.count += 1u;
        }
    }
    return walls;
}

// `Patches::covers`: whether the planar patch of triangle `id` (`t`), seen from its `side`,
// covers the disc of radius `need` around `p`, a point of it: no edge of the patch open from
// that side comes closer.
fn patch_covers(id: u32, t: Triangle, side: u32, p: vec3<f32>, need: f32) -> bool {
    let info = triangle_info[id];
    if info.patch_count == PATCH_CLOSED {
        return true;
    }
    if info.patch_count == 0u {
        let mask = select(info.patch_start >> 3u, info.patch_start, side == SIDE_FRONT);
        let v = array<vec3<f32>, 3>(t.p0, t.p1, t.p2);
        for (var k = 0u; k < 3u; k++) {
            if (mask & (1u << k)) != 0u && segment_distance(p, v[k], v[(k + 1u) % 3u]) < need {
                return false;
            }
        }
        return true;
    }
    // The patch's sides are its first triangle's.
    let patch_side = select(side, side ^ (SIDE_FRONT | SIDE_BACK), (info.flags & TRI_PATCH_FLIPPED) != 0u);
    for (var i = 0u; i < info.patch_count; i++) {
        let e = patch_edges[info.patch_start + i];
        if (e.sides & patch_side) != 0u && segment_distance(p, e.a, e.b) < need {
            return false;
        }
    }
    return true;
}

// `patches::segment_distance`: the distance from `p` to the segment from `a` to `b`.
fn segment_distance(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> f32 {
    let ab = b - a;
    let len2 = dot(ab, ab);
    let s = select(0.0, clamp(dot(p - a, ab) / len2, 0.0, 1.0), len2 > 0.0);
    return distance(p, a + ab * s);
}

// The closest hits of the six probes from `o` with t in (tmin[k], tmax), the twins of six
// `closest_hit` (or `closest_hit_beyond`) calls, found in one traversal of the BVH; a probe
// with tmin[k] < 0 is not traced: lavapipe caps the loop iterations of
// an invocation (`lib/gather_entry.wgsl`), and six traversals a pair reached the cap where a
// record gathers every light. hits[k] is probe k's (`probe_axis`), t < 0 for none.
fn probe_hits(o: vec3<f32>, tmin: array<f32, 6>, tmax: f32) -> array<Hit, 6> {
    let none = Hit(-1.0, 0u, 0.0, 0.0);
    var hits = array<Hit, 6>(none, none, none, none, none, none);
    var best = array<f32, 6>(tmax, tmax, tmax, tmax, tmax, tmax);
    for (var k = 0u; k < MAX_WALLS; k++) {
        if tmin[k] < 0.0 {
            best[k] = -1.0;
        }
    }
    let d = array<vec3<f32>, 6>(probe_axis(0u), probe_axis(1u), probe_axis(2u), probe_axis(3u), probe_axis(4u), probe_axis(5u));
    let rays = array<TriangleRay, 6>(
        triangle_ray(o, d[0]), triangle_ray(o, d[1]), triangle_ray(o, d[2]),
        triangle_ray(o, d[3]), triangle_ray(o, d[4]), triangle_ray(o, d[5]),
    );
    let inv = array<vec3<f32>, 6>(
        safe_inverse(d[0]), safe_inverse(d[1]), safe_inverse(d[2]),
        safe_inverse(d[3]), safe_inverse(d[4]), safe_inverse(d[5]),
    );
    var i = 0u;
    while i < scene_info.node_count {
        let node = nodes[i];
        // Entered when any probe still reaches it (no loop: each turn counts against the cap).
        let entered = box_entry(node.lo, node.hi, o, inv[0], best[0]) < NO_ENTRY
            || box_entry(node.lo, node.hi, o, inv[1], best[1]) < NO_ENTRY
            || box_entry(node.lo, node.hi, o, inv[2], best[2]) < NO_ENTRY
            || box_entry(node.lo, node.hi, o, inv[3], best[3]) < NO_ENTRY
            || box_entry(node.lo, node.hi, o, inv[4], best[4]) < NO_ENTRY
            || box_entry(node.lo, node.hi, o, inv[5], best[5]) < NO_ENTRY;
        if entered && node.count > 0u {
            for (var k = node.first; k < node.first + node.count; k++) {
                let tri = leaf_triangle(k);
                probe_triangle(&hits, &best, rays[0], 0u, tmin[0], tri);
                probe_triangle(&hits, &best, rays[1], 1u, tmin[1], tri);
                probe_triangle(&hits, &best, rays[2], 2u, tmin[2], tri);
                probe_triangle(&hits, &best, rays[3], 3u, tmin[3], tri);
                probe_triangle(&hits, &best, rays[4], 4u, tmin[4], tri);
                probe_triangle(&hits, &best, rays[5], 5u, tmin[5], tri);
            }
        }
        i = next_node(i, node, entered);
    }
    return hits;
}

// Probe `k` (ray `r`) against `tri`: a hit beyond `tmin` and closer than its best so far
// replaces it.
fn probe_triangle(hits: ptr<function, array<Hit, 6>>, best: ptr<function, array<f32, 6>>, r: TriangleRay, k: u32, tmin: f32, tri: Triangle) {
    let h = intersect_triangle(r, tri.p0, tri.p1, tri.p2, tmin, (*best)[k]);
    if h.x >= 0.0 {
        (*best)[k] = h.x;
        (*hits)[k] = Hit(h.x, tri.id, h.y, h.z);
    }
}
