//! Where the variance of `vbl`'s `Lss` draws comes from (the twin of `lmm_variance` for VSLs
//! seen from camera shading points). For one pass of a scene, a sample of shading points is
//! gathered against every VSL of the pass, each pair estimated `PAIRS` times (mean c_i,
//! variance v_i), and each light's probability p_i in the tree's descent read off. One draw
//! then has variance
//!
//!   V = Σ (c_i² + v_i)/p_i − C² = [Σ c_i²/p_i − C²] (selection) + Σ v_i/p_i (pair sampling),
//!
//! printed summed over the sample relative to Σ C² (a draw's relative variance), beside the
//! same for lights drawn uniformly and for the ideal selection (p ∝ √(c² + v)).
//!
//! Settings by environment: SCENE (assets/scenes/cars_small.toml), WIDTH (160), HEIGHT (90),
//! PASS (4, for the radius), RECORDS (300), PAIRS (32), SEED (1).
//!
//! `cargo run --release --example lss_variance`
use beamlight_render::radius::{default_radius, paths_squared_radius};
use beamlight_scene::{luminance_mean, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    light_tree::{LightTree, Receiver},
    vbl::{VblSettings, vsl_to_surface},
};

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let scene_path: String = env("SCENE", "assets/scenes/cars_small.toml".to_string());
    let (width, height): (u32, u32) = (env("WIDTH", 160), env("HEIGHT", 90));
    let pass: u32 = env("PASS", 4);
    let records: usize = env("RECORDS", 300);
    let pairs: u32 = env("PAIRS", 32);
    let seed: u32 = env("SEED", 1);
    let scene = beamlight_scene::load::load_scene(std::path::Path::new(&scene_path)).expect("scene");
    let ts = TraceScene::new(scene);
    let paths = 64;
    let r2 = paths_squared_radius(default_radius(&ts.scene), 0.7, paths, pass);
    let r = r2.sqrt();
    let lights = trace_light_paths(&ts, &LightTracerSettings::default(), paths, seed, pass);
    let camera = trace_camera_paths(&ts, &CameraPathSettings::default(), width, height, seed ^ 0x55, pass);
    let tree = LightTree::over_vsls(&ts.scene, &lights.vpls);
    let settings = VblSettings::default();
    let points = &camera.shading_points;
    let step = (points.len() / records.max(1)).max(1);
    println!(
        "{scene_path}: {} VSLs from {paths} paths, {} shading points ({} sampled), R = {r:.4}",
        lights.vpls.len(),
        points.len(),
        points.len().div_ceil(step)
    );
    let (mut sel, mut pair, mut ideal, mut c2, mut uniform) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut worst: Vec<(f64, String)> = Vec::new();
    let mut zero_mass = 0.0f64;
    let mut flat = 0.0f64;
    let mut shared = 0.0f64;
    let depth: u32 = env("CUT", 4);
    let mut cut_var = 0.0f64;
    // The nodes of the cut: every node at `depth`, and leaves above it.
    let mut cut_nodes = Vec::new();
    let mut stack = vec![(0usize, 0u32)];
    while let Some((at, d)) = stack.pop() {
        let n = &tree.nodes[at];
        if n.is_leaf() || d == depth {
            cut_nodes.push(at);
        } else {
            stack.push((n.child as usize, d + 1));
            stack.push((n.child as usize + 1, d + 1));
        }
    }
    let share: usize = env("SHARE", 16);
    let leaves: Vec<usize> = (0..lights.vpls.len())
        .map(|i| {
            tree.nodes
                .iter()
                .position(|n| n.is_leaf() && n.light() as usize == i)
                .unwrap_or(usize::MAX)
        })
        .collect();
    for (k, sp) in points.iter().enumerate().step_by(step) {
        let rx = Receiver::at_point(&ts.scene, sp);
        let p = tree.pmfs(&rx, r, lights.vpls.len());
        // Every leaf by its own importance (no interior nodes), 10 % by weight.
        let imp: Vec<f64> = leaves
            .iter()
            .map(|&n| {
                if n == usize::MAX {
                    0.0
                } else {
                    beamlight_trace::light_tree::importance(&tree.nodes[n], &rx, r) as f64
                }
            })
            .collect();
        let wts: Vec<f64> = leaves
            .iter()
            .map(|&n| {
                if n == usize::MAX {
                    0.0
                } else {
                    tree.nodes[n].weight as f64
                }
            })
            .collect();
        let (isum, wsum) = (imp.iter().sum::<f64>(), wts.iter().sum::<f64>());
        let q: Vec<f64> = imp
            .iter()
            .zip(&wts)
            .map(|(i, w)| 0.9 * i / isum.max(1e-300) + 0.1 * w / wsum)
            .collect();
        // The same with the masses of the first of SHARE consecutive records.
        let first_rx = Receiver::at_point(&ts.scene, &points[k - k % share]);
        let imp_s: Vec<f64> = leaves
            .iter()
            .map(|&n| {
                if n == usize::MAX {
                    0.0
                } else {
                    beamlight_trace::light_tree::importance(&tree.nodes[n], &first_rx, r) as f64
                }
            })
            .collect();
        let isum_s = imp_s.iter().sum::<f64>();
        let q_s: Vec<f64> = imp_s
            .iter()
            .zip(&wts)
            .map(|(i, w)| 0.9 * i / isum_s.max(1e-300) + 0.1 * w / wsum)
            .collect();
        let mut shared_k = 0.0f64;
        let cut_imp: Vec<f64> = cut_nodes
            .iter()
            .map(|&n| beamlight_trace::light_tree::importance(&tree.nodes[n], &rx, r) as f64)
            .collect();
        let cut_w: Vec<f64> = cut_nodes.iter().map(|&n| tree.nodes[n].weight as f64).collect();
        let (ci, cw) = (cut_imp.iter().sum::<f64>(), cut_w.iter().sum::<f64>());
        let mut p_cut = vec![0.0f64; lights.vpls.len()];
        for (j, &n) in cut_nodes.iter().enumerate() {
            let pn = 0.9 * cut_imp[j] / ci.max(1e-300) + 0.1 * cut_w[j] / cw;
            for (l, x) in pmfs_from(&tree, n, &rx, r, lights.vpls.len()).into_iter().enumerate() {
                p_cut[l] += pn * x;
            }
        }
        let mut cut_k = 0.0f64;
        let mut flat_k = 0.0f64;
        let (mut c_sum, mut sqrt_sum, mut sum_c2_plus_v) = (0.0f64, 0.0f64, 0.0f64);
        let mut each: Vec<(f64, usize, f64)> = Vec::new();
        for (i, vpl) in lights.vpls.iter().enumerate() {
            let mut s = Sampler::new(seed ^ 0x1234, k as u32, i as u32);
            let (mut m, mut m2) = (0.0f64, 0.0f64);
            for _ in 0..pairs {
                let x = luminance_mean(vsl_to_surface(&ts, sp, vpl, r2, &settings, &mut s)) as f64;
                m += x;
                m2 += x * x;
            }
            let c = m / pairs as f64;
            let v = (m2 / pairs as f64 - c * c).max(0.0) * pairs as f64 / (pairs as f64 - 1.0);
            c_sum += c;
            each.push((p[i], i, c));
            sqrt_sum += (c * c + v).sqrt();
            sum_c2_plus_v += c * c + v;
            if q[i] > 0.0 {
                flat_k += c * c / q[i];
            }
            if p_cut[i] > 0.0 {
                cut_k += c * c / p_cut[i];
            }
            if q_s[i] > 0.0 {
                shared_k += c * c / q_s[i];
            }
            if p[i] > 0.0 {
                sel += c * c / p[i];
                pair += v / p[i];
                if c == 0.0 {
                    zero_mass += p[i];
                }
                let (x, q) = (glam::Vec3::from(sp.pos), glam::Vec3::from(vpl.pos));
                let w = (q - x).normalize();
                worst.push((
                    c * c / p[i],
                    format!(
                        "point {k} (mat {}) light {i} (mat {}): d {:.3}, cos rx {:.2}, cos light {:.2}, p {:.2e}, c/C {:.3}",
                        sp.material,
                        vpl.material,
                        (q - x).length(),
                        w.dot(glam::Vec3::from(sp.normal)),
                        (-w).dot(glam::Vec3::from(vpl.normal)),
                        p[i],
                        c / 1.0,
                    ),
                ));
            } else if c > 0.0 {
                println!("light {i} contributes {c:.3e} to point {k} but is never drawn");
            }
        }
        sel -= c_sum * c_sum;
        flat += flat_k - c_sum * c_sum;
        shared += shared_k - c_sum * c_sum;
        cut_var += cut_k - c_sum * c_sum;
        if std::env::var("SHOW").is_ok_and(|t| t.split(',').any(|x| x == format!("{k}"))) {
            each.sort_by(|a, b| b.0.total_cmp(&a.0));
            println!(
                "point {k} (mat {}, n {:?}), C = {c_sum:.3}: most probable lights",
                sp.material, sp.normal
            );
            for &(pi, i, c) in each.iter().take(12) {
                let (x, q) = (glam::Vec3::from(sp.pos), glam::Vec3::from(lights.vpls[i].pos));
                let w = (q - x).normalize();
                println!(
                    "  light {i} (mat {}) p {pi:.3} c {c:.3} d {:.3} cos rx {:.2} cos light {:.2} weight {:.3e}",
                    lights.vpls[i].material,
                    (q - x).length(),
                    w.dot(glam::Vec3::from(sp.normal)),
                    (-w).dot(glam::Vec3::from(lights.vpls[i].normal)),
                    beamlight_trace::light_tree::vsl_weight(&ts.scene, &lights.vpls[i])
                );
            }
        }
        ideal += sqrt_sum * sqrt_sum - c_sum * c_sum;
        uniform += lights.vpls.len() as f64 * sum_c2_plus_v - c_sum * c_sum;
        c2 += c_sum * c_sum;
    }
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!("largest terms c²/p relative to Σ C²:");
    for (x, text) in worst.iter().take(env("WORST", 15)) {
        println!("  {:.3}  {text}", x / c2);
    }
    println!(
        "mean probability of drawing a light that gives nothing: {:.3}",
        zero_mass / points.len().div_ceil(step) as f64
    );
    println!("relative variance of one draw (Σ over points / Σ C²):");
    println!("  selection      {:.3}", sel / c2);
    println!("  pair sampling  {:.3}", pair / c2);
    println!("  flat selection by each leaf's importance: {:.3}", flat / c2);
    println!(
        "  flat over the {} nodes at depth {depth}, then the descent: {:.3}",
        cut_nodes.len(),
        cut_var / c2
    );
    println!(
        "  flat, the masses of the first of {share} consecutive records: {:.3}",
        shared / c2
    );
    println!("  total          {:.3}", (sel + pair) / c2);
    println!(
        "  ideal p ∝ √(c² + v): {:.3}; uniform p: {:.3}",
        ideal / c2,
        uniform / c2
    );
}

/// Each light's probability of being drawn by a descent from node `start`.
fn pmfs_from(tree: &LightTree, start: usize, rx: &Receiver, r: f32, lights: usize) -> Vec<f64> {
    use beamlight_trace::light_tree::importance;
    let mut out = vec![0.0; lights];
    let mut stack = vec![(start, 1.0f64)];
    while let Some((at, p)) = stack.pop() {
        let node = tree.nodes[at];
        if node.is_leaf() {
            out[node.light() as usize] += p;
            continue;
        }
        let c = node.child as usize;
        let (a, b) = (importance(&tree.nodes[c], rx, r), importance(&tree.nodes[c + 1], rx, r));
        if !(a + b > 0.0) {
            continue;
        }
        let (wl, wr) = (tree.nodes[c].weight, tree.nodes[c + 1].weight);
        let p_left = if a > 0.0 && b > 0.0 {
            0.9 * a / (a + b) + 0.1 * wl / (wl + wr)
        } else {
            a / (a + b)
        };
        stack.push((c, p * p_left as f64));
        stack.push((c + 1, p * (1.0 - p_left) as f64));
    }
    out
}
