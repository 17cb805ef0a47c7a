//! The virtual-light gathers on the GPU: one kernel per transport component and method, each
//! the twin of a CPU estimator (`shaders/vpl_surface.wgsl` ↔ `vpl::vpl_to_surface`, …). A pass
//! uploads its gather and light records, dispatches the kernels the scene needs in one
//! submission (each timed by timestamp queries), and reads every result back once.
use crate::{
    Gpu, GpuError, GpuScene,
    compute::{self, Kernel, Slot, Timer},
    layout::{self, ANGULAR_PDF_VBL, ANGULAR_PDF_VRL, BSDF_LAMBERT, BSDF_NONE, BSDF_PHONG, GatherParams},
};
use beamlight_scene::{Rgb, Scene, bsdf};
pub use beamlight_trace::gather::GatherInputs;
use beamlight_trace::{
    camera_paths::{MediaSegment, ShadingPoint},
    light_tree::{Drawing, FLAT_GROUP, LightTreeNode},
    vbl::AngularPdf,
};
use glam::Vec2;

/// The gather kernels: a transport component times a method (the `vrl` family's virtual
/// ray/point lights, or `vbl`'s virtual beam/spherical lights of the pass's radius).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherKernel {
    /// `Lss`: VPLs at shading points.
    VplSurface,
    /// `Lsm`: VRLs at shading points.
    VrlSurface,
    /// `Lms`: VPLs along camera media segments.
    VplMedia,
    /// `Lmm`: VRLs along camera media segments.
    VrlMedia,
    /// `Lss`: VSLs at shading points.
    VslSurface,
    /// `Lsm`: VBLs at shading points.
    VblSurface,
    /// `Lms`: VSLs along camera media segments.
    VslMedia,
    /// `Lmm`: VBLs along camera media segments.
    VblMedia,
}

/// Kernels in a [`Gathered`] result: every [`GatherKernel`].
pub const KERNELS: usize = 8;

impl GatherKernel {
    pub const ALL: [GatherKernel; KERNELS] = [
        Self::VplSurface,
        Self::VrlSurface,
        Self::VplMedia,
        Self::VrlMedia,
        Self::VslSurface,
        Self::VblSurface,
        Self::VslMedia,
        Self::VblMedia,
    ];
    /// The `vrl`/`vrl-clamped` kernels, in (Lss, Lsm, Lms, Lmm) order.
    pub const RAYS: [GatherKernel; 4] = [Self::VplSurface, Self::VrlSurface, Self::VplMedia, Self::VrlMedia];
    /// The `vbl` kernels, in (Lss, Lsm, Lms, Lmm) order.
    pub const BEAMS: [GatherKernel; 4] = [Self::VslSurface, Self::VblSurface, Self::VslMedia, Self::VblMedia];

    pub fn file(self) -> &'static str {
        match self {
            Self::VplSurface => "vpl_surface.wgsl",
            Self::VrlSurface => "vrl_surface.wgsl",
            Self::VplMedia => "vpl_media.wgsl",
            Self::VrlMedia => "vrl_media.wgsl",
            Self::VslSurface => "vsl_surface.wgsl",
            Self::VblSurface => "vbl_surface.wgsl",
            Self::VslMedia => "vsl_media.wgsl",
            Self::VblMedia => "vbl_media.wgsl",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::VplSurface => "Lss (VPL)",
            Self::VrlSurface => "Lsm (VRL)",
            Self::VplMedia => "Lms (VPL)",
            Self::VrlMedia => "Lmm (VRL)",
            Self::VslSurface => "Lss (VSL)",
            Self::VblSurface => "Lsm (VBL)",
            Self::VslMedia => "Lms (VSL)",
            Self::VblMedia => "Lmm (VBL)",
        }
    }

    pub fn on_surfaces(self) -> bool {
        matches!(
            self,
            Self::VplSurface | Self::VrlSurface | Self::VslSurface | Self::VblSurface
        )
    }

    pub fn reads_vpls(self) -> bool {
        matches!(
            self,
            Self::VplSurface | Self::VplMedia | Self::VslSurface | Self::VslMedia
        )
    }

    /// Whether the kernel's WGSL is compiled in (every kernel is; a method uses the GPU only
    /// when all four of its kernels are, so a kernel can be left out while it is written).
    pub fn available(self) -> bool {
        crate::shaders::SOURCES.iter().any(|(n, _)| *n == self.file())
    }
}

/// A BSDF in the kernels' form, its texture looked up at `uv` (the CPU's `Scene::bsdf_at`).
pub fn resolve_bsdf(scene: &Scene, material: u32, uv: Vec2) -> layout::Bsdf {
    match scene.bsdf_at(material, Some(uv)) {
        Some(bsdf::Bsdf::Lambert { albedo }) => layout::Bsdf {
            diffuse: albedo.into(),
            kind: BSDF_LAMBERT,
            ..Default::default()
        },
        Some(bsdf::Bsdf::Phong {
            diffuse,
            specular,
            exponent,
        }) => layout::Bsdf {
            diffuse: diffuse.into(),
            // The CPU's exponent sanitising: NaN → 0, at most 1e7.
            exponent: if exponent.is_nan() {
                0.0
            } else {
                exponent.clamp(0.0, 1e7)
            },
            specular: specular.into(),
            kind: BSDF_PHONG,
        },
        _ => layout::Bsdf {
            kind: BSDF_NONE,
            ..Default::default()
        },
    }
}

impl GatherKernel {
    /// Gather records this kernel runs over in `inputs`.
    pub fn records(self, inputs: &GatherInputs) -> usize {
        if self.on_surfaces() {
            inputs.shading_points.len()
        } else {
            inputs.media_segments.len()
        }
    }

    /// Virtual lights this kernel reads in `inputs`.
    pub fn lights(self, inputs: &GatherInputs) -> usize {
        if self.reads_vpls() {
            inputs.vpls.len()
        } else {
            inputs.vrls.len()
        }
    }
}

/// Per gather record, each kernel's estimate (empty for kernels not run), the GPU time each
/// kernel took (0 without timestamp queries or when not run), and how many estimates each
/// discarded (the WGSL `admit`: NaN, infinite or negative, counted per record in its w).
#[derive(Clone, Debug, Default)]
pub struct Gathered {
    pub results: [Vec<Rgb>; KERNELS],
    pub kernel_seconds: [f64; KERNELS],
    pub discarded: [u64; KERNELS],
}

pub struct Gathers {
    /// Indexed by [`GatherKernel`]; `None` for kernels not compiled (not asked for, or not
    /// written yet).
    kernels: Vec<Option<Kernel>>,
    /// At most this many gather records per dispatch (beyond what the binding limit allows).
    chunk_limit: usize,
}

/// The most (record, light) pairs one dispatch evaluates: 2¹⁶, about 40 ms of the slowest
/// kernel (`Lsm` with VBLs, 1.7 M pairs/s) on lavapipe; a display GPU's watchdog allows
/// seconds.
const PAIRS_PER_DISPATCH: usize = 1 << 16;

/// Lights an all-pairs gather's invocation takes per dispatch. lavapipe stops every loop of an
/// invocation once it has run 65 535 loop iterations in all (`GpuError::LoopCap`); a VBL pair
/// costs up to about 900 (a shadow ray's and the walls' BVH traversals, the angular PDF's
/// vertices, the cone's directions; more with `--vsl-directions 100 --pdf-vertices 64`), so 32
/// lights stay well below it. The rest of the lights follow in further dispatches.
pub const LIGHTS_PER_DISPATCH: usize = 32;

/// The slots of bind group 1 (see `lib/gather.wgsl`).
const GATHER_SLOTS: [Slot; 11] = [
    Slot::Uniform,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::ReadWrite,
    // The light trees and the flat draw's masses (`lib/light_tree.wgsl`).
    Slot::Read,
    Slot::Read,
    // The walls next to each VPL (`lib/vbl.wgsl`).
    Slot::Read,
];

impl Gathers {
    /// Compiles the kernels in `only` that are written (see [`GatherKernel::available`]), each
    /// on a thread of its own: on a CPU adapter (lavapipe) a pipeline is compiled by LLVM when
    /// it is created, a third of a second per kernel, and the kernels compile independently.
    /// A render compiles its method's four kernels, not all eight.
    pub fn new(gpu: &Gpu, scene: &GpuScene, only: &[GatherKernel]) -> Result<Gathers, GpuError> {
        let layout = compute::bind_group_layout(gpu, "gather", &GATHER_SLOTS);
        let compile = |k: GatherKernel| Kernel::new(gpu, k.file(), vec![scene.layout.clone(), layout.clone()]);
        let wanted: Vec<GatherKernel> = GatherKernel::ALL
            .into_iter()
            .filter(|k| only.contains(k) && k.available())
            .collect();
        let compiled: Vec<(GatherKernel, Result<Kernel, GpuError>)> = std::thread::scope(|scope| {
            let handles: Vec<_> = wanted.iter().map(|&k| (k, scope.spawn(move || compile(k)))).collect();
            handles
                .into_iter()
                .map(|(k, h)| (k, h.join().unwrap_or_else(|e| std::panic::resume_unwind(e))))
                .collect()
        });
        let mut kernels: Vec<Option<Kernel>> = (0..KERNELS).map(|_| None).collect();
        for (k, kernel) in compiled {
            kernels[k as usize] = Some(kernel?);
        }
        Ok(Gathers {
            kernels,
            chunk_limit: usize::MAX,
        })
    }

    /// Splits every kernel's records into dispatches of at most `records` (a multiple of 16),
    /// as the binding limit does for large images: for tests, which cannot afford gigabytes.
    pub fn set_chunk_limit(&mut self, records: usize) {
        assert!(records >= 16 && records.is_multiple_of(16));
        self.chunk_limit = records;
    }

    /// Records per dispatch: as many as one storage binding holds of the largest record
    /// (a shading point), rounded down to a multiple of 16 so that every chunk's byte offset
    /// (a multiple of 16 records of 16, 32, 48, 64 or 80 bytes) is a multiple of 256, the largest
    /// storage-offset alignment an adapter may demand.
    /// Dispatches are also sized by work: at most [`PAIRS_PER_DISPATCH`] (record, light)
    /// pairs each (`pairs_per_record` is the lights a record gathers or draws), so that no
    /// dispatch runs long enough for a display GPU's watchdog to kill it.
    /// A multiple of 16 is also a multiple of the flat draw's group
    /// ([`beamlight_trace::light_tree::FLAT_GROUP`]), so a group never spans two dispatches.
    fn records_per_dispatch(&self, gpu: &Gpu, pairs_per_record: usize) -> usize {
        const { assert!(16 % FLAT_GROUP == 0) };
        let fits = compute::max_binding(gpu) as usize / size_of::<ShadingPoint>();
        let work = PAIRS_PER_DISPATCH / pairs_per_record.max(1);
        (fits.min(work) / 16 * 16).clamp(16, self.chunk_limit)
    }

    /// Runs the kernels with `run[k]` set and returns their results, read back once.
    pub fn run(
        &self,
        gpu: &Gpu,
        scene: &GpuScene,
        ts_scene: &Scene,
        inputs: &GatherInputs,
        run: [bool; KERNELS],
    ) -> Result<Gathered, GpuError> {
        self.submit(gpu, scene, ts_scene, inputs, run)?.finish(gpu)
    }

    /// Uploads the records and submits the kernels with `run[k]` set; the GPU works while the
    /// caller does something else, until [`PendingGathers::finish`].
    pub fn submit(
        &self,
        gpu: &Gpu,
        scene: &GpuScene,
        ts_scene: &Scene,
        inputs: &GatherInputs,
        run: [bool; KERNELS],
    ) -> Result<PendingGathers, GpuError> {
        // A kernel asked for but not compiled is the caller's bug (it opened the GPU for
        // another method): an error, not a component left black.
        if let Some(k) = GatherKernel::ALL
            .into_iter()
            .find(|&k| run[k as usize] && self.kernels[k as usize].is_none())
        {
            return Err(GpuError::Shader(format!(
                "the kernel {} was asked for but not compiled",
                k.file()
            )));
        }
        let wanted = |k: GatherKernel| run[k as usize] && k.records(inputs) > 0 && k.lights(inputs) > 0;
        // Upload only what a dispatched kernel reads.
        let any = |f: fn(GatherKernel) -> bool| GatherKernel::ALL.iter().any(|&k| wanted(k) && f(k));
        let (need_points, need_segments) = (any(|k| k.on_surfaces()), any(|k| !k.on_surfaces()));
        let (need_vpls, need_vrls) = (any(|k| k.reads_vpls()), any(|k| !k.reads_vpls()));
        // Record arrays may exceed one storage binding (a 1080p image has 166 MB of shading
        // points); each dispatch binds a chunk of them that fits.
        let points = compute::storage_unbound(
            gpu,
            "shading points",
            if need_points { inputs.shading_points } else { &[] },
        )?;
        let point_bsdfs: Vec<layout::Bsdf> = if need_points {
            inputs
                .shading_points
                .iter()
                .map(|sp| resolve_bsdf(ts_scene, sp.material, Vec2::from(sp.uv)))
                .collect()
        } else {
            Vec::new()
        };
        let point_bsdfs = compute::storage_unbound(gpu, "shading point BSDFs", &point_bsdfs)?;
        let segments = compute::storage_unbound(
            gpu,
            "media segments",
            if need_segments { inputs.media_segments } else { &[] },
        )?;
        let vpls = compute::storage(gpu, "VPLs", if need_vpls { inputs.vpls } else { &[] })?;
        let vpl_bsdfs: Vec<layout::Bsdf> = if need_vpls {
            inputs
                .vpls
                .iter()
                .map(|v| resolve_bsdf(ts_scene, v.material, Vec2::new(v.u, v.v)))
                .collect()
        } else {
            Vec::new()
        };
        let vpl_bsdfs = compute::storage(gpu, "VPL BSDFs", &vpl_bsdfs)?;
        let vrls = compute::storage(gpu, "VRLs", if need_vrls { inputs.vrls } else { &[] })?;
        // The VSL kernels read each VPL's walls, found on the CPU once per pass.
        let need_walls = any(|k| k.reads_vpls() && GatherKernel::BEAMS.contains(&k));
        if need_walls && inputs.vpl_walls.len() != inputs.vpls.len() {
            return Err(GpuError::Inputs(format!(
                "{} VPLs but the walls of {}",
                inputs.vpls.len(),
                inputs.vpl_walls.len()
            )));
        }
        let vpl_walls: Vec<layout::Walls> = if need_walls {
            inputs.vpl_walls.iter().map(layout::Walls::from).collect()
        } else {
            Vec::new()
        };
        let vpl_walls = compute::storage(gpu, "VPL walls", &vpl_walls)?;
        // Both trees in one binding: the VSL tree's nodes, then the VBL tree's.
        let trees: Vec<LightTreeNode> = inputs.vsl_tree.iter().chain(inputs.vbl_tree).copied().collect();
        let trees = compute::storage(gpu, "light trees", &trees)?;

        let (masses, stride) = flat_masses(gpu, inputs, wanted(GatherKernel::VblMedia))?;

        let mut timer = Timer::new(gpu, KERNELS as u32);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let mut outputs: Vec<(GatherKernel, wgpu::Buffer, usize)> = Vec::new();
        let mut timed = Vec::new();
        for k in GatherKernel::ALL.into_iter().filter(|&k| wanted(k)) {
            let (records, lights) = (k.records(inputs), k.lights(inputs));
            let samples = if k == GatherKernel::VblMedia {
                inputs.media_light_samples
            } else {
                inputs.light_samples
            };
            let drawn = samples > 0 && GatherKernel::BEAMS.contains(&k);
            // Work per record in pairs: its drawn ones, or every light's; a flat draw (`Lmm`)
            // also walks its group's masses (a read and an add per VBL).
            let flat = drawn && k == GatherKernel::VblMedia && inputs.media_drawing == Drawing::Flat;
            // An all-pairs gather takes its lights in chunks, one dispatch each: lavapipe caps
            // the loop iterations of an invocation (`GpuError::LoopCap`).
            let light_chunk = if drawn { lights } else { lights.min(LIGHTS_PER_DISPATCH) };
            let work = match (drawn, flat) {
                (true, true) => samples as usize + lights.div_ceil(64),
                (true, false) => samples as usize,
                (false, _) => light_chunk,
            };
            let chunk = self.records_per_dispatch(gpu, work);
            let out = compute::output_unbound::<[f32; 4]>(gpu, "gathered", records)?;
            let kernel = self.kernels[k as usize].as_ref().expect("wanted kernels exist");
            // All of one kernel's dispatches go into one timed compute pass.
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(kernel.name),
                timestamp_writes: timer.next_pass(),
            });
            pass.set_pipeline(&kernel.pipeline);
            pass.set_bind_group(0, &scene.bind_group, &[]);
            for (first, first_light) in (0..records)
                .step_by(chunk)
                .flat_map(|first| (0..lights.max(1)).step_by(light_chunk.max(1)).map(move |l| (first, l)))
            {
                let n = chunk.min(records - first);
                let (x, y, row) = compute::dispatch_size(gpu, n as u32);
                let params = GatherParams {
                    pair_seed: inputs.pair_seed,
                    pass_index: inputs.pass,
                    records: n as u32,
                    lights: lights as u32,
                    row,
                    clamp: inputs.clamp,
                    scale: 1.0 / inputs.paths.max(1) as f32,
                    radius2: inputs.radius2,
                    directions: inputs.vbl.directions,
                    pdf_vertices: inputs.vbl.pdf_vertices,
                    uniform_share: inputs.vbl.uniform_share,
                    angular_pdf: match inputs.vbl.pdf {
                        AngularPdf::Vbl => ANGULAR_PDF_VBL,
                        AngularPdf::Vrl => ANGULAR_PDF_VRL,
                    },
                    record_offset: first as u32,
                    light_samples: samples,
                    vsl_tree_nodes: inputs.vsl_tree.len() as u32,
                    vbl_tree_nodes: inputs.vbl_tree.len() as u32,
                    poison: if inputs.inject_nan { f32::NAN.to_bits() } else { 0 },
                    media_drawing: (inputs.media_drawing == Drawing::Flat) as u32,
                    first_light: first_light as u32,
                    light_chunk: light_chunk as u32,
                };
                let params = compute::uniform(gpu, "gather params", &params);
                // This chunk's records; of the other kind's array (unused) just its start.
                fn chunk_of(
                    buffer: &wgpu::Buffer,
                    first: usize,
                    n: usize,
                    size: usize,
                    ours: bool,
                ) -> compute::Binding<'_> {
                    if ours {
                        compute::Binding::range(buffer, (first * size) as u64, (n * size) as u64)
                    } else {
                        compute::Binding::range(buffer, 0, buffer.size().min(size as u64))
                    }
                }
                // The chunk's groups' rows of masses (its first record is a multiple of 16).
                let masses_of_chunk = if flat {
                    let row = (stride * size_of::<f32>()) as u64;
                    let groups = n.div_ceil(FLAT_GROUP) as u64;
                    compute::Binding::range(&masses, (first / FLAT_GROUP) as u64 * row, groups * row)
                } else {
                    compute::Binding::range(&masses, 0, size_of::<f32>() as u64)
                };
                let on_surfaces = k.on_surfaces();
                let group = compute::bind_group_ranges(
                    gpu,
                    kernel.name,
                    &kernel.layouts[1],
                    &[
                        compute::Binding::Whole(&params),
                        chunk_of(&points, first, n, size_of::<ShadingPoint>(), on_surfaces),
                        chunk_of(&point_bsdfs, first, n, size_of::<layout::Bsdf>(), on_surfaces),
                        chunk_of(&segments, first, n, size_of::<MediaSegment>(), !on_surfaces),
                        compute::Binding::Whole(&vpls),
                        compute::Binding::Whole(&vpl_bsdfs),
                        compute::Binding::Whole(&vrls),
                        chunk_of(&out, first, n, 16, true),
                        compute::Binding::Whole(&trees),
                        masses_of_chunk,
                        compute::Binding::Whole(&vpl_walls),
                    ],
                );
                pass.set_bind_group(1, &group, &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
            drop(pass);
            timed.push(k);
            outputs.push((k, out, records));
        }
        // One staging buffer for every result: a single copy and a single map per pass.
        let total: u64 = outputs.iter().map(|(_, _, n)| (*n * 16) as u64).sum();
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("gathered readback"),
            size: total.max(16),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut offset = 0u64;
        let mut layout = Vec::new();
        for (k, buffer, records) in &outputs {
            let bytes = (*records * 16) as u64;
            encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset, bytes);
            layout.push((*k, *records));
            offset += bytes;
        }
        timer.resolve(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        gpu.check()?;
        Ok(PendingGathers {
            staging,
            layout,
            timed,
            timer,
        })
    }
}

/// The masses a flat `Lmm` draw takes its lights by (`flat_masses` in `lib/light_tree.wgsl`):
/// row g the pmfs of group g's leaves in node order ([`GatherInputs::media_masses`]), each row
/// padded to a multiple of 64 values (256 bytes, the largest storage-offset alignment), so
/// that a dispatch of whole groups binds its rows. Returns the buffer and the row's stride;
/// one zero when nothing draws flat.
fn flat_masses(gpu: &Gpu, inputs: &GatherInputs, vbl_media: bool) -> Result<(wgpu::Buffer, usize), GpuError> {
    let drawn = vbl_media && inputs.media_light_samples > 0 && inputs.media_drawing == Drawing::Flat;
    if !drawn {
        return Ok((compute::storage_unbound::<f32>(gpu, "flat masses", &[])?, 0));
    }
    let leaves = inputs.vbl_tree.iter().filter(|n| n.is_leaf()).count();
    let groups = inputs.media_segments.len().div_ceil(FLAT_GROUP);
    if inputs.media_masses.len() != groups || inputs.media_masses.iter().any(|g| !g.is_empty() && g.len() != leaves) {
        return Err(GpuError::Inputs(format!(
            "a flat draw over {leaves} VBLs for {groups} groups of media segments has masses for {} groups",
            inputs.media_masses.len()
        )));
    }
    // The kernel strides by (nodes + 1) / 2 leaves (`flat_stride`), a binary tree's.
    if leaves != inputs.vbl_tree.len().div_ceil(2) {
        return Err(GpuError::Inputs(format!(
            "a VBL tree of {} nodes has {leaves} leaves, not a binary tree's",
            inputs.vbl_tree.len()
        )));
    }
    let stride = leaves.next_multiple_of(64).max(64);
    let mut table = vec![0.0f32; groups * stride];
    for (row, group) in table.chunks_exact_mut(stride).zip(inputs.media_masses) {
        // An empty group (no VBL with any weight) draws nothing: its row stays zero.
        for (slot, &(_, pmf)) in row.iter_mut().zip(group) {
            *slot = pmf;
        }
    }
    Ok((compute::storage_unbound(gpu, "flat masses", &table)?, stride))
}

/// Gathers submitted to the GPU and not yet read back.
pub struct PendingGathers {
    staging: wgpu::Buffer,
    /// Each kernel's results, one after the other in `staging`: (kernel, records).
    layout: Vec<(GatherKernel, usize)>,
    timed: Vec<GatherKernel>,
    timer: Timer,
}

impl PendingGathers {
    /// Waits for the GPU and reads every result back.
    pub fn finish(mut self, gpu: &Gpu) -> Result<Gathered, GpuError> {
        let total: usize = self.layout.iter().map(|(_, n)| n).sum();
        let values: Vec<[f32; 4]> = compute::map_and_copy(gpu, &self.staging, total)?;
        let mut gathered = Gathered::default();
        let mut at = 0;
        for (k, n) in self.layout {
            let records = &values[at..at + n];
            // −1: the driver stopped the invocation's loops early (`lib/gather_entry.wgsl`).
            let cut = records.iter().filter(|v| v[3] < 0.0).count();
            if cut > 0 {
                return Err(GpuError::LoopCap {
                    kernel: k.file(),
                    records: cut,
                });
            }
            gathered.results[k as usize] = records.iter().map(|v| Rgb::new(v[0], v[1], v[2])).collect();
            gathered.discarded[k as usize] = records.iter().map(|v| v[3] as u64).sum();
            at += n;
        }
        for (k, seconds) in self.timed.into_iter().zip(self.timer.read(gpu)?) {
            gathered.kernel_seconds[k as usize] = seconds;
        }
        Ok(gathered)
    }
}
