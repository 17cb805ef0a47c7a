//! The command line's words: clap types for every command and their parsers.
use crate::runs;
use anyhow::Result;
use beamlight_render::{
    Method,
    backend::Backend,
    components::Component,
    many_lights,
    many_lights::{MediaDraw, VslDraw},
};
use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "beamlight",
    version,
    about = "Progressive virtual beam lights: a renderer for participating media"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Render a scene (TOML sidecar, or a .gltf/.glb alone) to a linear-RGB OpenEXR image.
    Render(Box<RenderArgs>),
    /// Compare two EXR images: RMSE, relMSE, MAE and maximum absolute error (B is the reference).
    Compare {
        a: PathBuf,
        b: PathBuf,
        /// Also compare every component layer the two files share (one line each).
        #[arg(long)]
        layers: bool,
    },
    /// Describe a scene: geometry, materials, media, emitters, backend.
    Info { scene: PathBuf },
    /// Write the scene for Mitsuba 3 (XML, PLY meshes and .vol grids beside it), saying what
    /// could not be exported exactly.
    ExportMitsuba {
        scene: PathBuf,
        output: PathBuf,
        /// Override the scene's image width.
        #[arg(long)]
        width: Option<u32>,
        /// Override the scene's image height.
        #[arg(long)]
        height: Option<u32>,
    },
    /// A labelled contact sheet (PNG). With one EXR: every layer of it, the beauty image and each
    /// transport component (paper Fig. 9). With several: the beauty image of each, side by side
    /// (equal-time comparisons). Each tile is tonemapped on its own unless --exposure is given.
    Sheet {
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Tile labels for several inputs, comma-separated (default: the file names).
        #[arg(long, value_delimiter = ',')]
        labels: Vec<String>,
        #[arg(short, long)]
        output: PathBuf,
        /// Tiles per row.
        #[arg(long, default_value_t = 4)]
        columns: u32,
        /// Each tile's luminance percentile (0–1) that maps to white.
        #[arg(long, default_value_t = 0.995)]
        percentile: f32,
        /// One exposure in stops for every tile instead (keeps brightness comparable).
        #[arg(long, allow_negative_numbers = true)]
        exposure: Option<f32>,
        /// Average N×N pixel blocks of every image first (smaller sheets of large renders).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
        downsample: u32,
    },
    /// Merge the accumulators of adjacent pass ranges (`render --passes A..B`) into one image.
    Merge {
        /// Accumulator files (`.accum`), in any order.
        parts: Vec<PathBuf>,
        /// The whole range the parts must cover, `A..B` (or `N` for `0..N`); without it, from
        /// the first part's start to the last part's end.
        #[arg(long)]
        passes: Option<runs::PassRange>,
        /// Output OpenEXR file; its accumulators are written beside it (`.accum`).
        #[arg(short, long)]
        output: PathBuf,
        /// Also write a tonemapped sRGB PNG preview.
        #[arg(long)]
        preview: Option<PathBuf>,
        /// Exposure of the preview in stops.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
    },
}

/// `--method`: the render crate's [`Method`]s, by their names.
#[derive(Clone, Copy)]
pub(crate) struct MethodArg(pub(crate) Method);

impl ValueEnum for MethodArg {
    fn value_variants<'a>() -> &'a [Self] {
        static ALL: std::sync::LazyLock<[MethodArg; Method::ALL.len()]> =
            std::sync::LazyLock::new(|| Method::ALL.map(MethodArg));
        &*ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name()).help(self.0.summary()))
    }
}

/// `--media-light-draw`: the render crate's [`MediaDraw`]s.
#[derive(Clone, Copy)]
pub(crate) struct MediaDrawArg(pub(crate) MediaDraw);

impl ValueEnum for MediaDrawArg {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            MediaDrawArg(MediaDraw::Auto),
            MediaDrawArg(MediaDraw::Descent),
            MediaDrawArg(MediaDraw::Flat),
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name()))
    }
}

/// `--vsl-draw`: the render crate's [`VslDraw`]s.
#[derive(Clone, Copy)]
pub(crate) struct VslDrawArg(pub(crate) VslDraw);

impl ValueEnum for VslDrawArg {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            VslDrawArg(VslDraw::Auto),
            VslDrawArg(VslDraw::Descent),
            VslDrawArg(VslDraw::Flat),
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name()))
    }
}

/// `--backend`: the render crate's [`Backend`]s.
#[derive(Clone, Copy)]
pub(crate) struct BackendArg(pub(crate) Backend);

impl ValueEnum for BackendArg {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            BackendArg(Backend::Auto),
            BackendArg(Backend::Gpu),
            BackendArg(Backend::Cpu),
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(match self.0 {
            Backend::Auto => "auto",
            Backend::Gpu => "gpu",
            Backend::Cpu => "cpu",
        }))
    }
}

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    pub(crate) scene: PathBuf,
    /// Output OpenEXR file (float32 linear RGB).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// The estimator (`auto`, the default: each component from the path tracer and `vbl`,
    /// whichever lowers its error faster).
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) method: MethodArg,
    /// Number of progressive passes, or a range `A..B` of the global pass sequence (one part
    /// of a render split across machines: its accumulators are written for `beamlight merge`).
    #[arg(long, conflicts_with_all = ["spp", "time"])]
    pub(crate) passes: Option<runs::PassRange>,
    /// Camera samples per pixel: passes of one sample each, but for `auto`, rounds of 16
    /// path-traced samples and one `vbl` pass (rounded up).
    #[arg(long, conflicts_with = "time")]
    pub(crate) spp: Option<u64>,
    /// Wall-clock budget in seconds, start-up included.
    #[arg(long)]
    pub(crate) time: Option<f64>,
    /// Random seed: the same seed and settings give the same image. `auto` draws its
    /// path-traced samples and its `vbl` passes from the streams `pt` and `vbl` use with it.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u32,
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) backend: BackendArg,
    /// Override the scene's image width.
    #[arg(long)]
    pub(crate) width: Option<u32>,
    /// Override the scene's image height.
    #[arg(long)]
    pub(crate) height: Option<u32>,
    /// Also write a tonemapped sRGB PNG preview.
    #[arg(long)]
    pub(crate) preview: Option<PathBuf>,
    /// Exposure of the preview in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub(crate) exposure: f32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// Maximum scattering events per path (`pt`); 1 = direct light / single scattering only.
    #[arg(long)]
    pub(crate) max_depth: Option<u32>,
    /// Also write each transport component (direct, Lsm, Lmm, Lms, Lss, caustic_surface,
    /// caustic_volume) as its own EXR layer; `pt` classifies its paths the same way.
    #[arg(long)]
    pub(crate) components: bool,
    /// Estimate only these components (comma-separated layer names, e.g. `Lmm,Lms`); the
    /// others stay black and cost nothing (not with `auto`, which picks its own). In `pt`,
    /// paths that can reach none of them end early, and in homogeneous media a ray whose next
    /// surface could feed only the others collides for sure, so a component alone converges
    /// 1.7-3.9x faster than within the whole image; the many-light methods skip the other
    /// components' gathers. Implies `--components`.
    #[arg(long, value_name = "LIST", value_parser = parse_component_list)]
    pub(crate) only: Option<ComponentList>,
    /// Light paths traced per pass by the many-light methods (each leaves several VPLs/VRLs;
    /// at most 1 048 576).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_LIGHT_PATHS as i64))]
    pub(crate) light_paths: u32,
    /// `vbl`: virtual lights each gather record draws per component from the pass's light
    /// tree (1–1024), or `all` to gather every light of the pass (the all-pairs estimator).
    #[arg(long, default_value_t = LightSamples(Some(many_lights::DEFAULT_LIGHT_SAMPLES)), value_name = "N|all", value_parser = parse_light_samples)]
    pub(crate) light_samples: LightSamples,
    /// `vbl`: virtual beam lights each camera media segment draws for `Lmm` (1–1024; default:
    /// as `--light-samples`). More can pay in homogeneous glossy fog, where `Lmm`'s draws are
    /// the noisiest (see docs/rendering.md)
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub(crate) media_light_samples: Option<u32>,
    /// `vbl`: how camera media segments draw their virtual beam lights for `Lmm`: `flat`,
    /// weighing every beam of the pass by its pair integral with both phase functions for
    /// each 4x4 tile of pixels (at equal time `Lmm` noise 23x lower than the descent in the
    /// glossy fog box, 2.4x in the smoke box), `descent` down the light tree (cheaper when a
    /// pass has very many beams), or `auto`: flat up to 4096 beams a pass (fewer in large
    /// images, whose per-tile masses must fit in 2^25), the descent beyond (see
    /// docs/rendering.md)
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) media_light_draw: MediaDrawArg,
    /// `vbl`: how shading points and camera media segments draw their virtual spherical
    /// lights for `Lss` and `Lms` on the CPU: `flat`, each record weighing every VSL of the
    /// pass (a draw's variance 8-15x lower than the descent's in the Cornell boxes and
    /// cars_small), `descent` down the light tree (cheaper when a pass has very many), or
    /// `auto`: flat up to 1024 VSLs a pass. The GPU's kernels descend (see docs/rendering.md)
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) vsl_draw: VslDrawArg,
    /// Many-light methods: camera samples per pixel per pass for direct light (its own pixel
    /// jitter and next-event estimate each; the gathers use one).
    #[arg(long, default_value_t = many_lights::DEFAULT_DIRECT_SAMPLES, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub(crate) direct_samples: u32,
    /// Many-light methods: light paths traced per pass for the surface caustics (photon
    /// mapping), apart from the gathers' `--light-paths` (default: 4 per pixel, at least
    /// 32 768 and at most 4 194 304; at most 16 777 216 given).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_CAUSTIC_PATHS as i64))]
    pub(crate) caustic_paths: Option<u32>,
    /// Many-light methods: light paths traced per pass for the volume caustics (photon
    /// beams; each costs a lookup per camera media segment it crosses; at most 4 194 304).
    #[arg(long, default_value_t = many_lights::DEFAULT_BEAM_PATHS, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_BEAM_PATHS as i64))]
    pub(crate) beam_paths: u32,
    /// `vrl-clamped`: minimum distance in the 1/d² falloff (default: 5 % of the scene's diagonal).
    #[arg(long)]
    pub(crate) clamp_distance: Option<f32>,
    /// `vbl`: initial radius R0 of the virtual beam and spherical lights, in scene units
    /// (default: 10 % of the scene's diagonal).
    #[arg(long)]
    pub(crate) radius: Option<f32>,
    /// Initial radius of the caustics' photon mapping and photon beams, in scene units
    /// (default: 2.5 % of the scene's diagonal).
    #[arg(long)]
    pub(crate) photon_radius: Option<f32>,
    /// Also write the image (EXR and preview) every SECONDS while rendering, atomically, so
    /// an interrupted render leaves its latest state readable.
    #[arg(long, value_name = "SECONDS")]
    pub(crate) write_every: Option<f64>,
    /// `vbl`: directions integrating each virtual spherical light's solid angle (paper eq. 9;
    /// the paper uses up to 100).
    #[arg(long, default_value_t = beamlight_render::VblSettings::default().directions, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub(crate) vsl_directions: u32,
    /// `vbl`: most vertices of the piecewise-linear angular PDFs (fewer for segments that
    /// subtend small angles).
    #[arg(long, default_value_t = beamlight_render::VblSettings::default().pdf_vertices, value_parser = clap::value_parser!(u32).range(2..=64))]
    pub(crate) pdf_vertices: u32,
    /// Radius reduction α of the paper's eq. 11, in (0, 1); smaller shrinks faster.
    #[arg(long, default_value_t = 0.7)]
    pub(crate) alpha: f32,
    /// Many-light methods: the most memory a pass's light paths may take, in GiB (default:
    /// 80 % of the memory available when the render starts, `MemAvailable` on Linux). The
    /// records per path are measured by tracing a few of each set first; a pass estimated
    /// beyond the limit is refused before it starts, naming the count to lower.
    #[arg(long, value_name = "GIB")]
    pub(crate) memory_limit: Option<f64>,
    /// Testing only (hidden): the many-light methods poison the first record of each gather
    /// of every pass with a NaN, on the CPU and the GPU, and the first path of each light set,
    /// so that a test can read the counts back through `--stats`, `--stats-json` and the EXR
    /// header.
    #[arg(long, hide = true)]
    pub(crate) inject_nan: bool,
    /// Save the accumulators (running sums, pass count, settings) to FILE every
    /// `--write-every` seconds (default 60) and at the end, atomically.
    #[arg(long, value_name = "FILE")]
    pub(crate) checkpoint: Option<PathBuf>,
    /// Continue the render saved in FILE (same scene and settings): `--passes N` then counts
    /// all passes, the saved ones included.
    #[arg(long, value_name = "FILE", conflicts_with = "spp")]
    pub(crate) resume: Option<PathBuf>,
    /// Print where the passes' time went: CPU tracing, CPU estimates, waiting for the GPU,
    /// and each GPU kernel's time (from timestamp queries).
    #[arg(long)]
    pub(crate) stats: bool,
    /// Write the run's timings as JSON to FILE (for `cargo xtask bench`): process time with
    /// and without start-up, passes, and the CPU and GPU seconds of each transport component.
    #[arg(long, value_name = "FILE")]
    pub(crate) stats_json: Option<PathBuf>,
}

/// `--only`: which components, by `Component::ALL` index.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ComponentList(pub(crate) [bool; Component::ALL.len()]);

pub(crate) fn parse_component_list(s: &str) -> Result<ComponentList, String> {
    let mut list = [false; Component::ALL.len()];
    for name in s.split(',').map(str::trim) {
        let Some(k) = Component::ALL.iter().position(|c| c.name() == name) else {
            let names: Vec<&str> = Component::ALL.iter().map(|c| c.name()).collect();
            return Err(format!("'{name}' is not a component (one of {})", names.join(", ")));
        };
        list[k] = true;
    }
    Ok(ComponentList(list))
}

/// `--light-samples`: a count, or `None` for all pairs.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightSamples(pub(crate) Option<u32>);

impl std::fmt::Display for LightSamples {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self.0 {
            Some(n) => write!(f, "{n}"),
            None => write!(f, "all"),
        }
    }
}

pub(crate) fn parse_light_samples(s: &str) -> Result<LightSamples, String> {
    if s == "all" {
        return Ok(LightSamples(None));
    }
    match s.parse::<u32>() {
        Ok(n) if (1..=1024).contains(&n) => Ok(LightSamples(Some(n))),
        _ => Err(format!("'{s}' is neither a number of lights in 1..=1024 nor 'all'")),
    }
}
