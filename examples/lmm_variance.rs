//! Issue 34's measurement: where the variance of `vbl`'s `Lmm` draws comes from. For one pass
//! of a scene (its light paths and one camera ray per pixel), a sample of camera media segments
//! is gathered against every VBL of the pass, each pair estimated `PAIRS` times: per pair the
//! mean c_i and variance v_i of the pair estimate, per light its probability p_i in the light
//! tree. One draw of the tree then has variance
//!
//!   V = Σ (c_i² + v_i)/p_i − C² = [Σ c_i²/p_i − C²] (selection) + Σ v_i/p_i (pair sampling),
//!
//! C = Σ c_i, which this prints summed over the sample relative to Σ C² (so a draw's relative
//! variance) for the tree's descent, beside the same for a flat draw by `flat_importance`
//! (for the renderer's receiver, `flat_draw_receiver`)
//! (`--media-light-draw flat`), for lights drawn uniformly, and for the ideal selection
//! (p ∝ √(c² + v), the best for these pair samplers); the lights whose terms weigh most
//! (`WORST`, 12), with the descent's choices on the way to one of them (`TRACE=segment
//! LIGHT=light`); and what a flat importance and a pair cost.
//!
//! Settings by environment: SCENE (assets/scenes/cornell_glossy_fog.toml), SIZE (48), PASS
//! (32, for the radius), RECORDS (200), PAIRS (64), SEED (1), REPEAT (1: passes of the
//! importances' timing loop, for a profiler), SHARE (4: a flat draw whose masses are shared
//! by that many consecutive records: camera records are traced in 4×4 tiles of pixels, so 16
//! is a tile, the renderer's `light_tree::FLAT_GROUP`; OFFSET: which record of the run, by
//! default the renderer's `flat_group_representative`), MIX (a second record of the run whose
//! masses are averaged in), QUAD (0: a flat draw whose masses are
//! the pair integral itself, by a QUAD × QUAD midpoint rule along both lines with their
//! marched densities and transmittances, σs along the VBL taken within R as its leaf takes it,
//! and the transmittance between them unless BETWEEN=0; what a better importance could gain
//! at most, and the pairs where the flat draw loses most to it).
//!
//! `cargo run --release --example lmm_variance`
use beamlight_render::radius::{default_radius, paths_squared_radius};
use beamlight_scene::{luminance_mean, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    light_tree::{LightTree, Receiver, flat_draw_receiver},
    vbl::{VblSettings, vbl_to_media},
};
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let scene_path: String = env("SCENE", "assets/scenes/cornell_glossy_fog.toml".to_string());
    let size: u32 = env("SIZE", 48);
    let pass: u32 = env("PASS", 32);
    let records: usize = env("RECORDS", 200);
    let pairs: u32 = env("PAIRS", 64);
    let seed: u32 = env("SEED", 1);
    let scene = beamlight_scene::load::load_scene(std::path::Path::new(&scene_path)).expect("scene");
    let ts = TraceScene::new(scene);
    let paths = 64;
    let r2 = paths_squared_radius(default_radius(&ts.scene), 0.7, paths, pass);
    let r = r2.sqrt();
    let lights = trace_light_paths(&ts, &LightTracerSettings::default(), paths, seed, pass);
    let camera = trace_camera_paths(&ts, &CameraPathSettings::default(), size, size, seed ^ 0x55, pass);
    let tree = LightTree::over_vbls(&ts.scene, &lights.vrls, r);
    let settings = VblSettings::default();
    let segs = &camera.media_segments;
    let step = (segs.len() / records.max(1)).max(1);
    println!(
        "{scene_path}: {} VBLs from {paths} paths, {} media segments ({} sampled), R = {r:.4}",
        lights.vrls.len(),
        segs.len(),
        segs.len().div_ceil(step)
    );
    let (mut sel, mut pair, mut ideal, mut c2, mut uniform) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut evaluated = 0u64;
    let (mut flat_sel, mut shared_sel, mut quad_sel) = (0.0f64, 0.0f64, 0.0f64);
    // The shared flat draw's pair-sampling part, Σ v/p.
    let mut shared_pair = 0.0f64;
    let (quad, between): (usize, bool) = (env("QUAD", 0), env("BETWEEN", 1) != 0);
    // Where the flat draw loses most to the quadrature's: (c² + v)(1/p − 1/p_quad), the pair.
    let mut losses: Vec<(f64, String)> = Vec::new();
    let share: usize = env("SHARE", 4);
    // The worst terms: (their share of the sample's variance, description).
    let mut worst: Vec<(f64, String)> = Vec::new();
    let clock = Instant::now();
    for (k, seg) in segs.iter().enumerate().step_by(step) {
        let rx = Receiver::along_segment(&ts.scene, seg);
        let p = tree.pmfs(&rx, r, lights.vrls.len());
        // Flat selection by each leaf's own importance (no tree above it), 10 % by flux.
        let leaves: Vec<usize> = (0..lights.vrls.len()).map(|i| leaf_of(&tree, i)).collect();
        // A flat draw's masses from the leaves' importances (by light): 90 % by importance,
        // 10 % by weight, all by weight when no light has importance (`flat_mass`).
        let mix = |imp: Vec<f64>| -> Vec<f64> {
            let wts: Vec<f64> = leaves.iter().map(|&n| tree.nodes[n].weight as f64).collect();
            let (isum, wsum) = (imp.iter().sum::<f64>(), wts.iter().sum::<f64>());
            imp.iter()
                .zip(&wts)
                .map(|(i, w)| {
                    if isum > 0.0 {
                        0.9 * i / isum + 0.1 * w / wsum
                    } else {
                        w / wsum
                    }
                })
                .collect()
        };
        let masses = |rx: &Receiver| -> Vec<f64> {
            mix(leaves
                .iter()
                .map(|&n| tree.flat_importance(&tree.nodes[n], rx, r) as f64)
                .collect())
        };
        let flat = masses(&flat_draw_receiver(&ts.scene, seg));
        let quad_masses: Vec<f64> = if quad > 0 {
            mix(lights
                .vrls
                .iter()
                .map(|v| pair_integral(&ts.scene, seg, v, r, quad, between))
                .collect())
        } else {
            Vec::new()
        };
        // The same masses shared by a run of SHARE consecutive records (neighbouring pixels
        // of a 4×4 tile): every record of the run draws by one record's, the renderer's
        // choice unless OFFSET says.
        let offset = env("OFFSET", beamlight_trace::light_tree::flat_group_representative(share));
        let representative = (k - k % share + offset).min(segs.len() - 1);
        let shared = if let Some(second) = std::env::var("MIX").ok().and_then(|v| v.parse::<usize>().ok()) {
            // The mean of two records' masses (a mixture: every light either would draw).
            let other = (k - k % share + second).min(segs.len() - 1);
            let (a, b) = (
                masses(&flat_draw_receiver(&ts.scene, &segs[representative])),
                masses(&flat_draw_receiver(&ts.scene, &segs[other])),
            );
            a.iter().zip(&b).map(|(x, y)| 0.5 * (x + y)).collect()
        } else {
            masses(&flat_draw_receiver(&ts.scene, &segs[representative]))
        };
        let mut shared_k = 0.0f64;
        let mut flat_k = 0.0f64;
        let mut quad_k = 0.0f64;
        if std::env::var("TRACE").is_ok_and(|t| t.split(',').any(|x| x == format!("{k}"))) {
            // The descent to each of the worst lights: importances of both children per level.
            let light: usize = env("LIGHT", 0);
            let leaf = leaf_of(&tree, light);
            let mut path = vec![leaf];
            while path[0] != 0 {
                let at = path[0];
                let parent = tree
                    .nodes
                    .iter()
                    .position(|n| !n.is_leaf() && (n.child as usize == at || n.child as usize + 1 == at))
                    .unwrap();
                path.insert(0, parent);
            }
            for w in path.windows(2) {
                let c = tree.nodes[w[0]].child as usize;
                let (ia, ib) = (
                    beamlight_trace::light_tree::importance(&tree.nodes[c], &rx, r),
                    beamlight_trace::light_tree::importance(&tree.nodes[c + 1], &rx, r),
                );
                let took = if w[1] == c { "left" } else { "right" };
                let n = &tree.nodes[w[1]];
                println!(
                    "  level: left {ia:.2e} right {ib:.2e}, takes {took} (box {:?}..{:?}, weight {:.2e})",
                    n.lo, n.hi, n.weight
                );
            }
        }
        let (mut c_sum, mut sel_k, mut pair_k, mut sqrt_sum) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut sum_c2_plus_v = 0.0f64;
        let mut terms = Vec::new();
        for (i, vrl) in lights.vrls.iter().enumerate() {
            let mut s = Sampler::new(seed ^ 0x1234, k as u32, i as u32);
            let (mut m, mut m2) = (0.0f64, 0.0f64);
            for _ in 0..pairs {
                let x = luminance_mean(vbl_to_media(&ts, seg, vrl, r2, &settings, &mut s)) as f64;
                m += x;
                m2 += x * x;
            }
            evaluated += pairs as u64;
            let c = m / pairs as f64;
            let v = (m2 / pairs as f64 - c * c).max(0.0) * pairs as f64 / (pairs as f64 - 1.0);
            c_sum += c;
            sqrt_sum += (c * c + v).sqrt();
            sum_c2_plus_v += c * c + v;
            terms.push((i, c, v));
            if flat[i] > 0.0 {
                flat_k += (c * c + v) / flat[i];
            }
            if quad > 0 && quad_masses[i] > 0.0 {
                quad_k += (c * c + v) / quad_masses[i];
            }
            if shared[i] > 0.0 {
                shared_pair += v / shared[i];
                shared_k += (c * c + v) / shared[i];
            }
            if p[i] > 0.0 {
                sel_k += c * c / p[i];
                pair_k += v / p[i];
            } else if c > 0.0 {
                println!("light {i} contributes {c:.3e} to segment {k} but is never drawn");
            }
        }
        for &(i, c, v) in &terms {
            if p[i] > 0.0 {
                let vrl = &lights.vrls[i];
                let (o, d) = (glam::Vec3::from(seg.origin), glam::Vec3::from(seg.dir));
                let (a, e) = (glam::Vec3::from(vrl.origin), glam::Vec3::from(vrl.dir));
                let w = a - o;
                let n = d.cross(e);
                let gap = if n.length() > 1e-4 {
                    (w.dot(n) / n.length()).abs()
                } else {
                    w.cross(d).length()
                };
                worst.push((
                    (c * c + v) / p[i],
                    format!(
                        "seg {k} (len {:.2}) light {i} (len {:.2}, |cos| {:.2}, line gap {gap:.3}): p {:.2e} ideal {:.2e}, c/C {:.3}, √v/C {:.3}, imp {:.2e}",
                        seg.length,
                        vrl.length,
                        d.dot(e).abs(),
                        p[i],
                        (c * c + v).sqrt() / sqrt_sum,
                        c / c_sum,
                        v.sqrt() / c_sum,
                        beamlight_trace::light_tree::importance(&tree.nodes[leaf_of(&tree, i)], &rx, r),
                    ),
                ));
            }
        }
        for &(i, c, v) in terms.iter().filter(|_| quad > 0) {
            if flat[i] > 0.0 && quad_masses[i] > 0.0 {
                losses.push((
                    (c * c + v) * (1.0 / flat[i] - 1.0 / quad_masses[i]),
                    format!(
                        "seg {k} light {i}: c/C {:.3}, √v/C {:.3}, flat p {:.2e}, quadrature's p {:.2e}",
                        c / c_sum,
                        v.sqrt() / c_sum,
                        flat[i],
                        quad_masses[i]
                    ),
                ));
            }
        }
        sel += sel_k - c_sum * c_sum;
        flat_sel += flat_k - c_sum * c_sum;
        shared_sel += shared_k - c_sum * c_sum;
        quad_sel += quad_k - c_sum * c_sum;
        pair += pair_k;
        ideal += sqrt_sum * sqrt_sum - c_sum * c_sum;
        uniform += lights.vrls.len() as f64 * sum_c2_plus_v - c_sum * c_sum;
        c2 += c_sum * c_sum;
    }
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!("largest terms (c² + v)/p, relative to Σ C²:");
    for (x, text) in worst.iter().take(env("WORST", 12)) {
        println!("  {:.3}  {text}", x / c2);
    }
    if quad > 0 {
        losses.sort_by(|a, b| b.0.total_cmp(&a.0));
        println!("where the flat draw loses most to the quadrature's, (c² + v)(1/p − 1/p_quad) / Σ C²:");
        for (x, text) in losses.iter().take(env("WORST", 12)) {
            println!("  {:.3}  {text}", x / c2);
        }
    }
    // What the leaves' importance costs: every segment of the sample against every light.
    let timing = Instant::now();
    let mut acc = 0.0f32;
    let mut count = 0u64;
    for seg in segs
        .iter()
        .step_by(step)
        .cycle()
        .take(env("REPEAT", 1) * segs.len().div_ceil(step))
    {
        let rx = Receiver::along_segment(&ts.scene, seg);
        for n in tree.nodes.iter().filter(|n| n.is_leaf()) {
            acc += tree.flat_importance(n, &rx, r);
            count += 1;
        }
    }
    println!(
        "a leaf's importance costs {:.3} µs ({acc:.1e})",
        timing.elapsed().as_secs_f64() / count as f64 * 1e6
    );
    let per_pair = clock.elapsed().as_secs_f64() / evaluated as f64;
    println!("relative variance of one draw (Σ over segments / Σ C²):");
    println!("  selection      {:.3}", sel / c2);
    println!("  pair sampling  {:.3}", pair / c2);
    println!("  total          {:.3}", (sel + pair) / c2);
    println!(
        "  flat selection by the leaves' importance (no tree): {:.3}",
        flat_sel / c2
    );
    println!(
        "  flat, the masses of one of {share} consecutive records shared: {:.3} (pair sampling {:.3} of it)",
        shared_sel / c2,
        shared_pair / c2
    );
    if quad > 0 {
        println!("  flat by the pair integral (QUAD = {quad}): {:.3}", quad_sel / c2);
    }
    println!(
        "  ideal p ∝ √(c² + v): {:.3}; uniform p: {:.3}",
        ideal / c2,
        uniform / c2
    );
    println!(
        "a pair costs {:.2} µs (one thread, all pairs of the sample)",
        per_pair * 1e6
    );
}

/// The pair integral of a VBL and a camera segment by an n × n midpoint rule: light density
/// σs(y) T(y) along the VBL (σs within `r` of y, as [`VblStretch`]'s march takes it), σs(x)
/// T(x) along the camera segment, both HG phase functions at the pair's direction, the
/// transmittance between them (when `between`), over the distance² floored at r².
///
/// [`VblStretch`]: beamlight_trace::light_tree::VblStretch
fn pair_integral(
    scene: &beamlight_scene::Scene,
    seg: &beamlight_trace::camera_paths::MediaSegment,
    v: &beamlight_trace::light_paths::LightSegment,
    r: f32,
    n: usize,
    between: bool,
) -> f64 {
    use beamlight_scene::medium::Medium;
    use glam::Vec3;
    let (mv, mc) = (&scene.media[v.medium as usize], &scene.media[seg.medium as usize]);
    let hg = |g: f32, c: f32| {
        let q = 1.0 + g * g - 2.0 * g * c;
        (1.0 - g * g) / (q * q.sqrt())
    };
    // Optical depth between two points: a march of steps 0.02 long (at most 64).
    let depth = |m: &Medium, p: Vec3, q: Vec3| -> f32 {
        let steps = (((q - p).length() / 0.02).ceil() as usize).clamp(1, 64);
        let h = (q - p).length() / steps as f32;
        let sum: f32 = (0..steps)
            .map(|i| m.density_at(p + (q - p) * ((i as f32 + 0.5) / steps as f32)))
            .sum();
        sum * h * m.sigma_t().max_element()
    };
    // The points of a line and the light each scatters: σs (within `within` of it) × the
    // line's transmittance from its start × the step.
    let line = |m: &Medium, o: Vec3, d: Vec3, len: f32, within: f32| -> Vec<(Vec3, f32)> {
        let h = len / n as f32;
        let (sigma_s, sigma_t) = (m.sigma_s.max_element(), m.sigma_t().max_element());
        let mut tau = 0.0;
        (0..n)
            .map(|i| {
                let x = o + d * ((i as f32 + 0.5) * h);
                let density = m.density_at(x);
                let scattering = if within > 0.0 {
                    m.density_within(x, within)
                } else {
                    density
                };
                let light = sigma_s * scattering * (-(tau + 0.5 * sigma_t * density * h)).exp() * h;
                tau += sigma_t * density * h;
                (x, light)
            })
            .collect()
    };
    let e = Vec3::from(v.dir);
    let d = Vec3::from(seg.dir);
    let ys = line(mv, Vec3::from(v.origin), e, v.length, r);
    let xs = line(mc, Vec3::from(seg.origin), d, seg.length, 0.0);
    let mut total = 0.0f64;
    for &(y, ly) in ys.iter().filter(|p| p.1 > 0.0) {
        for &(x, lx) in xs.iter().filter(|p| p.1 > 0.0) {
            let w = (x - y).normalize_or_zero();
            let t = if between { (-depth(mc, y, x)).exp() } else { 1.0 };
            let f = hg(mv.g, e.dot(w)) * hg(mc.g, -w.dot(d));
            total += (ly * lx * t * f / (x - y).length_squared().max(r * r)) as f64;
        }
    }
    total * Vec3::from(v.power).max_element() as f64
}

/// The tree node holding light `i`.
fn leaf_of(tree: &LightTree, i: usize) -> usize {
    tree.nodes
        .iter()
        .position(|n| n.is_leaf() && n.light() as usize == i)
        .expect("every light has a leaf")
}
