//! What a pass's virtual-light gathers read, the same for the CPU estimators
//! (`beamlight_render`'s record gathers) and the GPU kernels (`beamlight_gpu::gather`).
use crate::{
    camera_paths::{MediaSegment, ShadingPoint},
    light_paths::{LightSegment, SurfaceVertex},
    light_tree::{Drawing, LightTreeNode},
    vbl::{VblSettings, Walls},
};

/// One pass's gather records and virtual lights, as the CPU traced them, and how they are
/// gathered.
#[derive(Clone, Copy)]
pub struct GatherInputs<'a> {
    pub shading_points: &'a [ShadingPoint],
    pub media_segments: &'a [MediaSegment],
    pub vpls: &'a [SurfaceVertex],
    /// The walls next to each VPL at the pass's radius (`vbl::vpl_walls_all`; the `vbl`
    /// kernels that gather from VPLs). Empty for the other methods.
    pub vpl_walls: &'a [Walls],
    pub vrls: &'a [LightSegment],
    /// Light paths traced (the M that every sum is divided by).
    pub paths: u32,
    pub pair_seed: u32,
    pub pass: u32,
    /// Minimum distance of the 1/d² falloff (0: unclamped).
    pub clamp: f32,
    /// The pass's squared VBL/VSL radius (the `vbl` kernels).
    pub radius2: f32,
    /// The VBL/VSL estimators' settings (the `vbl` kernels).
    pub vbl: VblSettings,
    /// Lights each record draws per kernel from the trees below (`vbl` kernels); 0 gathers
    /// every light.
    pub light_samples: u32,
    /// The same for the VBL → camera segment gather (`Lmm`), which may draw more.
    pub media_light_samples: u32,
    /// How the VBL → camera segment gather draws (`--media-light-draw`).
    pub media_drawing: Drawing,
    /// For a flat draw on the GPU: the masses each group of
    /// [`FLAT_GROUP`](crate::light_tree::FLAT_GROUP) media segments draws by
    /// ([`LightTree::group_masses`](crate::light_tree::LightTree::group_masses)). They are
    /// weighed on the CPU, as the trees are built there, so that both backends draw by the
    /// same bits (the GPU's `exp` and `log` are not libm's: its own masses would differ by
    /// rounding, and once in a while move a stratified number across a leaf's boundary).
    /// Empty otherwise.
    pub media_masses: &'a [Vec<(u32, f32)>],
    /// The pass's light trees over `vpls` and `vrls` (empty without light selection).
    pub vsl_tree: &'a [LightTreeNode],
    pub vbl_tree: &'a [LightTreeNode],
    /// Fault injection for the discard counters' tests (`ManyLightSettings::inject_nan` in
    /// the render crate): each gather's first record of the pass estimates NaN.
    pub inject_nan: bool,
}
