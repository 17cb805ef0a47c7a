//! `equiangular` of `shaders/lib/sampling.wgsl` against `beamlight_scene::sampling::equiangular`,
//! which it twins, query by query through the test kernel `shaders/test/sampling_probe.wgsl`:
//! intervals seen from close by and from far away, where the twins sample uniformly because
//! the end angles are too close to sample between (`sampling::subtends_no_angle`). Both must
//! take the same branch (a uniform density 1/(t1 − t0) on one side only fails, but for a few
//! queries right at the threshold, where the twins' atan2 may differ by an ulp) and agree in t
//! to 1e-5 of the problem's scale (|δ| + h, where t = δ + h·tan θ is computed) and in the
//! density to the larger of 1e-4 and 8 ulps of the end angles over their difference (the
//! density divides by θ1 − θ0, whose last bits are the twins' atan2 rounding: near the
//! threshold, 10⁻⁴ of the angles' size, that is up to about 10⁻³). A porting bug (a wrong
//! branch, a missing factor) is far outside both.
use beamlight_gpu::{
    compute::{self, Kernel, Slot},
    device,
};
use beamlight_scene::{
    rng::Sampler,
    sampling::{self, LineAngles},
};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// `EquiangularQuery` in `shaders/test/sampling_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct EquiangularQuery {
    o: [f32; 3],
    t0: f32,
    d: [f32; 3],
    t1: f32,
    c: [f32; 3],
    u: f32,
}

/// `Batch` in `shaders/test/sampling_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Batch {
    count: u32,
    row: u32,
    _pad: [u32; 2],
}

#[test]
fn equiangular_matches_cpu_near_and_far() {
    let Some(gpu) = device::for_tests() else { return };
    let mut s = Sampler::new(29, 0, 0);
    let mut queries = Vec::new();
    for k in 0..20_000 {
        let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5;
        let d = sampling::uniform_sphere(s.next_2d());
        let len = 10f32.powf(-3.0 + 3.0 * s.next_1d());
        // Half the points within a few units, half 10³–10⁵ away (the uniform branch).
        let far = if k % 2 == 0 {
            1.0
        } else {
            10f32.powf(3.0 + 2.0 * s.next_1d())
        };
        let c = o + sampling::uniform_sphere(s.next_2d()) * far * (0.1 + 2.0 * s.next_1d());
        queries.push(EquiangularQuery {
            o: o.into(),
            t0: 0.0,
            d: d.into(),
            t1: len,
            c: c.into(),
            u: s.next_1d(),
        });
    }
    let layout = compute::bind_group_layout(&gpu, "sampling batch", &[Slot::Uniform, Slot::Read, Slot::ReadWrite]);
    let kernel = Kernel::new(&gpu, "test/sampling_probe.wgsl", vec![layout]).unwrap();
    let (x, y, row) = compute::dispatch_size(&gpu, queries.len() as u32);
    let batch = Batch {
        count: queries.len() as u32,
        row,
        ..Default::default()
    };
    let params = compute::uniform(&gpu, "sampling batch", &batch);
    let input = compute::storage(&gpu, "equiangular queries", &queries).unwrap();
    let output = compute::output::<[f32; 2]>(&gpu, "equiangular results", queries.len()).unwrap();
    let group = compute::bind_group(&gpu, "sampling batch", &kernel.layouts[0], &[&params, &input, &output]);
    kernel.dispatch(&gpu, &[&group], (x, y));
    let gpu_results: Vec<[f32; 2]> = compute::read_back(&gpu, &output, queries.len()).unwrap();
    let (mut uniform, mut beyond, mut worst) = (0, Vec::new(), 0.0f32);
    for (k, (q, g)) in queries.iter().zip(&gpu_results).enumerate() {
        let (o, d, c) = (Vec3::from(q.o), Vec3::from(q.d), Vec3::from(q.c));
        let (t, pdf) = sampling::equiangular(o, d, q.t0, q.t1, c, q.u);
        let uniform_cpu = pdf == 1.0 / (q.t1 - q.t0);
        let uniform_gpu = g[1] == 1.0 / (q.t1 - q.t0);
        uniform += uniform_cpu as usize;
        assert!(
            pdf.is_finite() && pdf > 0.0 && g[1].is_finite() && g[1] > 0.0,
            "query {k}: cpu {pdf}, gpu {}",
            g[1]
        );
        let line = LineAngles::new(o, d, q.t0, q.t1, c, 0.0);
        let scale = line.delta.abs() + line.h;
        let angle_ulp = f32::EPSILON * line.theta0.abs().max(line.theta1.abs());
        let pdf_tolerance = (8.0 * angle_ulp / (line.theta1 - line.theta0)).max(1e-4);
        let t_error = (t - g[0]).abs() / scale;
        let pdf_error = (pdf - g[1]).abs() / pdf;
        worst = worst.max(pdf_error / pdf_tolerance).max(t_error / 1e-5);
        if uniform_cpu != uniform_gpu || t_error > 1e-5 || pdf_error > pdf_tolerance {
            beyond.push(format!(
                "query {k} ({q:?}): cpu ({t}, {pdf}) uniform {uniform_cpu}, gpu ({}, {}) uniform {uniform_gpu}",
                g[0], g[1]
            ));
        }
    }
    eprintln!(
        "{} queries, {uniform} sampled uniformly; {} beyond tolerance or on another branch; worst error {worst:.2} of its tolerance",
        queries.len(),
        beyond.len()
    );
    assert!(uniform > 5_000, "only {uniform} queries took the uniform branch");
    assert!(
        beyond.len() <= 10,
        "{} queries differ:\n{}",
        beyond.len(),
        beyond[..beyond.len().min(12)].join("\n")
    );
}
