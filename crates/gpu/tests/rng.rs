//! The WGSL random numbers are the CPU's, bit for bit, for 10^6 counters.
use beamlight_gpu::{
    compute::{self, Kernel, Slot},
    device,
};
use beamlight_scene::rng::{Sampler, hash4};
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    seed: u32,
    pass_index: u32,
    first: u32,
    count: u32,
    row: u32,
    _pad: [u32; 3],
}

#[test]
fn wgsl_rng_matches_cpu_bit_for_bit() {
    let Some(gpu) = device::for_tests() else { return };
    let layout = compute::bind_group_layout(&gpu, "rng", &[Slot::Uniform, Slot::ReadWrite, Slot::ReadWrite]);
    let kernel = Kernel::new(&gpu, "test/rng_bits.wgsl", vec![layout]).unwrap();
    let count = 1_000_000u32;
    for (seed, pass) in [(0u32, 0u32), (0xdead_beef, 12_345)] {
        let first = 3_000_000_000;
        let (x, y, row) = compute::dispatch_size(&gpu, count);
        let params = compute::uniform(
            &gpu,
            "params",
            &Params {
                seed,
                pass_index: pass,
                first,
                count,
                row,
                _pad: [0; 3],
            },
        );
        let bits = compute::output::<u32>(&gpu, "bits", count as usize).unwrap();
        let floats = compute::output::<f32>(&gpu, "floats", count as usize).unwrap();
        let group = compute::bind_group(&gpu, "rng", &kernel.layouts[0], &[&params, &bits, &floats]);
        kernel.dispatch(&gpu, &[&group], (x, y));
        let gpu_bits: Vec<u32> = compute::read_back(&gpu, &bits, count as usize).unwrap();
        let gpu_floats: Vec<f32> = compute::read_back(&gpu, &floats, count as usize).unwrap();
        for k in 0..count {
            let c = first.wrapping_add(k);
            assert_eq!(gpu_bits[k as usize], hash4(seed, pass, c >> 4, c & 15), "counter {c}");
            let f = Sampler::new(seed, pass, c).next_1d();
            assert_eq!(gpu_floats[k as usize].to_bits(), f.to_bits(), "counter {c}");
        }
    }
}
