//! Ray queries in bulk on the GPU (`shaders/trace_rays.wgsl`): closest hits and occlusion for
//! a batch of rays, with the kernel's own time from timestamp queries.
use crate::{
    Gpu, GpuError,
    compute::{self, Kernel, Slot, Timer},
    layout::{Hit, Ray, RayBatch},
    scene::GpuScene,
};

pub struct RayTracer {
    kernel: Kernel,
}

/// A batch's answers and the GPU time the kernel took (`None` without timestamp queries).
pub struct Traced {
    pub hits: Vec<Hit>,
    pub kernel_seconds: Option<f64>,
}

impl RayTracer {
    pub fn new(gpu: &Gpu, scene: &GpuScene) -> Result<RayTracer, GpuError> {
        let batch = compute::bind_group_layout(gpu, "ray batch", &[Slot::Uniform, Slot::Read, Slot::ReadWrite]);
        Ok(RayTracer {
            kernel: Kernel::new(gpu, "trace_rays.wgsl", vec![scene.layout.clone(), batch])?,
        })
    }

    pub fn trace(&self, gpu: &Gpu, scene: &GpuScene, rays: &[Ray]) -> Result<Traced, GpuError> {
        let (x, y, row) = compute::dispatch_size(gpu, rays.len() as u32);
        let params = RayBatch {
            count: rays.len() as u32,
            row,
            ..Default::default()
        };
        let params = compute::uniform(gpu, "ray batch", &params);
        let input = compute::storage(gpu, "rays", rays)?;
        let output = compute::output::<Hit>(gpu, "hits", rays.len())?;
        let group = compute::bind_group(gpu, "ray batch", &self.kernel.layouts[1], &[&params, &input, &output]);
        let mut timer = Timer::new(gpu, 1);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace rays"),
                timestamp_writes: timer.next_pass(),
            });
            pass.set_pipeline(&self.kernel.pipeline);
            pass.set_bind_group(0, &scene.bind_group, &[]);
            pass.set_bind_group(1, &group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        timer.resolve(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        let hits = compute::read_back(gpu, &output, rays.len())?;
        let kernel_seconds = timer.read(gpu)?.first().copied();
        Ok(Traced { hits, kernel_seconds })
    }
}
