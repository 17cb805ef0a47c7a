//! Small helpers around wgpu compute: buffers within the adapter's limits, kernels with
//! explicit bind group layouts, 2-D dispatches past the 65 535-workgroup limit, readback and
//! timestamp queries.
use crate::{Gpu, GpuError, shaders};
use bytemuck::Pod;
use wgpu::util::DeviceExt;

/// Invocations per workgroup of every kernel (`@workgroup_size(64)` in the WGSL).
pub const WORKGROUP: u32 = 64;

/// What a kernel binding holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    Uniform,
    Read,
    ReadWrite,
}

fn layout_entries(slots: &[Slot]) -> Vec<wgpu::BindGroupLayoutEntry> {
    slots
        .iter()
        .enumerate()
        .map(|(i, slot)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: match slot {
                    Slot::Uniform => wgpu::BufferBindingType::Uniform,
                    Slot::Read => wgpu::BufferBindingType::Storage { read_only: true },
                    Slot::ReadWrite => wgpu::BufferBindingType::Storage { read_only: false },
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect()
}

/// A bind group layout whose binding `i` holds `slots[i]`.
pub fn bind_group_layout(gpu: &Gpu, label: &str, slots: &[Slot]) -> wgpu::BindGroupLayout {
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &layout_entries(slots),
    })
}

/// A bind group binding `buffers[i]` whole at binding `i`.
pub fn bind_group(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let whole: Vec<Binding> = buffers.iter().map(|b| Binding::Whole(b)).collect();
    bind_group_ranges(gpu, label, layout, &whole)
}

/// A buffer bound whole, or a byte range of it.
pub enum Binding<'a> {
    Whole(&'a wgpu::Buffer),
    Range {
        buffer: &'a wgpu::Buffer,
        offset: u64,
        size: u64,
    },
}

impl<'a> Binding<'a> {
    pub fn range(buffer: &'a wgpu::Buffer, offset: u64, size: u64) -> Binding<'a> {
        Binding::Range { buffer, offset, size }
    }
}

/// A bind group binding `bindings[i]` at binding `i`.
pub fn bind_group_ranges(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    bindings: &[Binding],
) -> wgpu::BindGroup {
    let entries: Vec<_> = bindings
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: match *b {
                Binding::Whole(buffer) => buffer.as_entire_binding(),
                Binding::Range { buffer, offset, size } => wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset,
                    size: std::num::NonZeroU64::new(size),
                }),
            },
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A compute pipeline for kernel `name` (a file under `shaders/`, entry point `main`), with
/// bind group `i` laid out as `groups[i]`.
pub struct Kernel {
    pub name: &'static str,
    pub pipeline: wgpu::ComputePipeline,
    pub layouts: Vec<wgpu::BindGroupLayout>,
}

impl Kernel {
    pub fn new(gpu: &Gpu, name: &'static str, groups: Vec<wgpu::BindGroupLayout>) -> Result<Kernel, GpuError> {
        let source = shaders::compose(name).map_err(|e| GpuError::Shader(e.to_string()))?;
        let module = gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let refs: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(Some).collect();
        let layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &refs,
            immediate_size: 0,
        });
        let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Ok(Kernel {
            name,
            pipeline,
            layouts: groups,
        })
    }

    /// Submits one untimed dispatch of `workgroups` (x, y) with bind group `i` set to
    /// `groups[i]` (the test kernels' one-shot runs; the renderer's dispatches are timed and
    /// chunked in `gather` and `rays`).
    pub fn dispatch(&self, gpu: &Gpu, groups: &[&wgpu::BindGroup], (x, y): (u32, u32)) {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            for (i, group) in groups.iter().enumerate() {
                pass.set_bind_group(i as u32, *group, &[]);
            }
            pass.dispatch_workgroups(x, y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
    }
}

/// Workgroups `(x, y)` covering `n` invocations, and the invocations per row (`x · 64`) the
/// kernel needs to recover its linear index: rows stay under the per-dimension limit.
pub fn dispatch_size(gpu: &Gpu, n: u32) -> (u32, u32, u32) {
    let groups = n.div_ceil(WORKGROUP).max(1);
    let max_x = gpu.limits.max_compute_workgroups_per_dimension.max(1);
    if groups <= max_x {
        (groups, 1, groups * WORKGROUP)
    } else {
        let y = groups.div_ceil(max_x);
        let x = groups.div_ceil(y);
        (x, y, x * WORKGROUP)
    }
}

/// The most bytes one storage binding may hold on this adapter.
pub fn max_binding(gpu: &Gpu) -> u64 {
    gpu.limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size)
}

/// Checks a storage buffer of `bytes` against the adapter's per-binding limit.
pub fn check_binding(gpu: &Gpu, what: &'static str, bytes: u64) -> Result<(), GpuError> {
    check_size(what, bytes, max_binding(gpu))
}

/// A read-only storage buffer holding `data` (one zeroed element when empty: bindings may
/// not be empty), bound whole.
pub fn storage<T: Pod>(gpu: &Gpu, what: &'static str, data: &[T]) -> Result<wgpu::Buffer, GpuError> {
    check_binding(gpu, what, (data.len().max(1) * size_of::<T>()) as u64)?;
    storage_unbound(gpu, what, data)
}

/// A read-only storage buffer holding `data`, which may exceed one binding (up to the
/// adapter's buffer size): the kernels bind ranges of it.
pub fn storage_unbound<T: Pod>(gpu: &Gpu, what: &'static str, data: &[T]) -> Result<wgpu::Buffer, GpuError> {
    let zero = [T::zeroed()];
    let data = if data.is_empty() { &zero[..] } else { data };
    let bytes: &[u8] = bytemuck::cast_slice(data);
    check_size(what, bytes.len() as u64, gpu.limits.max_buffer_size)?;
    Ok(gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(what),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    }))
}

fn check_size(what: &'static str, needed: u64, allowed: u64) -> Result<(), GpuError> {
    if needed > allowed {
        return Err(GpuError::Limit { what, needed, allowed });
    }
    Ok(())
}

/// A uniform buffer holding `value`.
pub fn uniform<T: Pod>(gpu: &Gpu, what: &'static str, value: &T) -> wgpu::Buffer {
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(what),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    })
}

/// A zeroed read-write storage buffer of `count` elements of `T`, readable back, bound whole.
pub fn output<T: Pod>(gpu: &Gpu, what: &'static str, count: usize) -> Result<wgpu::Buffer, GpuError> {
    check_binding(gpu, what, (count.max(1) * size_of::<T>()) as u64)?;
    output_unbound::<T>(gpu, what, count)
}

/// [`output`] for a buffer that may exceed one binding (bound in ranges).
pub fn output_unbound<T: Pod>(gpu: &Gpu, what: &'static str, count: usize) -> Result<wgpu::Buffer, GpuError> {
    let bytes = (count.max(1) * size_of::<T>()) as u64;
    check_size(what, bytes, gpu.limits.max_buffer_size)?;
    Ok(gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(what),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    }))
}

/// Copies the first `count` elements of `buffer` back to the CPU (waits for the queue).
pub fn read_back<T: Pod>(gpu: &Gpu, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<T>, GpuError> {
    let bytes = (count * size_of::<T>()) as u64;
    if bytes == 0 {
        return Ok(Vec::new());
    }
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
    gpu.queue.submit([encoder.finish()]);
    map_and_copy(gpu, &staging, count)
}

/// Maps a `MAP_READ` buffer (after the work writing it was submitted) and copies it out.
pub fn map_and_copy<T: Pod>(gpu: &Gpu, staging: &wgpu::Buffer, count: usize) -> Result<Vec<T>, GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    gpu.check()?;
    rx.recv()
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    let out = {
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| GpuError::Readback(format!("{e:?}")))?;
        bytemuck::cast_slice::<u8, T>(&view)[..count].to_vec()
    };
    staging.unmap();
    Ok(out)
}

/// GPU time of compute passes, from timestamp queries (where the adapter has them).
pub struct Timer {
    queries: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    capacity: u32,
    used: u32,
    period_ns: f64,
}

impl Timer {
    /// Room for `passes` timed compute passes between [`Timer::reset`]s.
    pub fn new(gpu: &Gpu, passes: u32) -> Timer {
        let capacity = passes * 2;
        let queries = gpu.timestamps.then(|| {
            let set = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: capacity,
            });
            let bytes = capacity as u64 * 8;
            let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: bytes,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp readback"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        Timer {
            queries,
            capacity,
            used: 0,
            period_ns: gpu.queue.get_timestamp_period() as f64,
        }
    }

    /// Timestamp writes for the next compute pass (`None` when full or unsupported).
    pub fn next_pass(&mut self) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let (set, _, _) = self.queries.as_ref()?;
        if self.used + 2 > self.capacity {
            return None;
        }
        let i = self.used;
        self.used += 2;
        Some(wgpu::ComputePassTimestampWrites {
            query_set: set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        })
    }

    /// Adds the commands that make the timestamps readable; call before submitting.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some((set, resolve, read)) = &self.queries
            && self.used > 0
        {
            encoder.resolve_query_set(set, 0..self.used, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, read, 0, self.used as u64 * 8);
        }
    }

    /// Seconds each timed pass took (after the submission with [`Timer::resolve`] ran), and
    /// starts over. Empty without timestamp support.
    pub fn read(&mut self, gpu: &Gpu) -> Result<Vec<f64>, GpuError> {
        let used = std::mem::take(&mut self.used);
        let Some((_, _, read)) = &self.queries else {
            return Ok(Vec::new());
        };
        if used == 0 {
            return Ok(Vec::new());
        }
        let ticks: Vec<u64> = map_and_copy(gpu, read, used as usize)?;
        Ok(ticks
            .chunks(2)
            .map(|p| p[1].saturating_sub(p[0]) as f64 * self.period_ns * 1e-9)
            .collect())
    }
}
