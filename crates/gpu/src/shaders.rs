//! The WGSL sources under `shaders/` and how kernels are composed from them.
//!
//! WGSL has no include mechanism, so we add one, kept deliberately small: a file's leading
//! lines `//! use lib/NAME.wgsl` name the library files it builds on. [`compose`] emits those
//! files first (depth first, each at most once, in the order named), then the file itself.
//! A library file may also name `//! hooks`: what each kernel using it must define (WGSL
//! resolves names across the whole module, so a shared entry point can call them).
//! Helpers (random numbers, geometry, traversal, media, materials) thus exist once in
//! `shaders/lib/`, and every kernel in `shaders/` (or `shaders/test/`) says what it needs.
//! All sources are compiled into the binary; `tests/shaders.rs` checks that this table lists
//! every file on disk and that every kernel composes and validates with naga.

/// Every WGSL file, by its path under `shaders/`.
pub const SOURCES: &[(&str, &str)] = &[
    ("lib/rng.wgsl", include_str!("../../../shaders/lib/rng.wgsl")),
    ("lib/scene.wgsl", include_str!("../../../shaders/lib/scene.wgsl")),
    ("lib/geometry.wgsl", include_str!("../../../shaders/lib/geometry.wgsl")),
    ("lib/bvh.wgsl", include_str!("../../../shaders/lib/bvh.wgsl")),
    ("lib/media.wgsl", include_str!("../../../shaders/lib/media.wgsl")),
    ("lib/shading.wgsl", include_str!("../../../shaders/lib/shading.wgsl")),
    ("lib/gather.wgsl", include_str!("../../../shaders/lib/gather.wgsl")),
    ("lib/sampling.wgsl", include_str!("../../../shaders/lib/sampling.wgsl")),
    ("lib/walls.wgsl", include_str!("../../../shaders/lib/walls.wgsl")),
    ("lib/vbl.wgsl", include_str!("../../../shaders/lib/vbl.wgsl")),
    ("lib/angular.wgsl", include_str!("../../../shaders/lib/angular.wgsl")),
    (
        "lib/light_tree.wgsl",
        include_str!("../../../shaders/lib/light_tree.wgsl"),
    ),
    (
        "lib/gather_entry.wgsl",
        include_str!("../../../shaders/lib/gather_entry.wgsl"),
    ),
    (
        "lib/surface_record.wgsl",
        include_str!("../../../shaders/lib/surface_record.wgsl"),
    ),
    (
        "lib/media_record.wgsl",
        include_str!("../../../shaders/lib/media_record.wgsl"),
    ),
    ("trace_rays.wgsl", include_str!("../../../shaders/trace_rays.wgsl")),
    ("vpl_surface.wgsl", include_str!("../../../shaders/vpl_surface.wgsl")),
    ("vrl_surface.wgsl", include_str!("../../../shaders/vrl_surface.wgsl")),
    ("vpl_media.wgsl", include_str!("../../../shaders/vpl_media.wgsl")),
    ("vrl_media.wgsl", include_str!("../../../shaders/vrl_media.wgsl")),
    ("vsl_surface.wgsl", include_str!("../../../shaders/vsl_surface.wgsl")),
    ("vbl_surface.wgsl", include_str!("../../../shaders/vbl_surface.wgsl")),
    ("vsl_media.wgsl", include_str!("../../../shaders/vsl_media.wgsl")),
    ("vbl_media.wgsl", include_str!("../../../shaders/vbl_media.wgsl")),
    (
        "test/rng_bits.wgsl",
        include_str!("../../../shaders/test/rng_bits.wgsl"),
    ),
    (
        "test/media_probe.wgsl",
        include_str!("../../../shaders/test/media_probe.wgsl"),
    ),
    (
        "test/sampling_probe.wgsl",
        include_str!("../../../shaders/test/sampling_probe.wgsl"),
    ),
    (
        "test/walls_probe.wgsl",
        include_str!("../../../shaders/test/walls_probe.wgsl"),
    ),
];

/// The kernels: every source outside `lib/`.
pub fn kernels() -> impl Iterator<Item = &'static str> {
    SOURCES.iter().map(|(name, _)| *name).filter(|n| !n.starts_with("lib/"))
}

#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("shaders/{0}: no such WGSL file is compiled in")]
    Unknown(String),
    #[error("shaders/{0}: `use` cycle")]
    Cycle(String),
}

fn source(name: &str) -> Result<&'static str, ShaderError> {
    SOURCES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .ok_or_else(|| ShaderError::Unknown(name.to_owned()))
}

/// The files `name` uses, from its leading `//! use` lines.
pub fn uses(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .map_while(|l| l.trim().strip_prefix("//!"))
        .filter_map(|l| l.trim().strip_prefix("use "))
        .map(str::trim)
}

/// What a library file leaves to the kernels that use it, from its leading `//! hooks` lines:
/// the names (constants, types, functions) each such kernel defines. A file with hooks is a
/// template (the gather kernels' shared entry point) and is valid only inside a kernel.
pub fn hooks(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .map_while(|l| l.trim().strip_prefix("//!"))
        .filter_map(|l| l.trim().strip_prefix("hooks "))
        .flat_map(str::split_whitespace)
}

/// The complete WGSL of kernel `name` (a path under `shaders/`).
pub fn compose(name: &str) -> Result<String, ShaderError> {
    let mut out = String::new();
    let mut done = Vec::new();
    let mut active = Vec::new();
    append(name, &mut out, &mut done, &mut active)?;
    Ok(out)
}

fn append<'a>(
    name: &'a str,
    out: &mut String,
    done: &mut Vec<&'a str>,
    active: &mut Vec<&'a str>,
) -> Result<(), ShaderError> {
    if done.contains(&name) {
        return Ok(());
    }
    if active.contains(&name) {
        return Err(ShaderError::Cycle(name.to_owned()));
    }
    let text = source(name)?;
    active.push(name);
    for dep in uses(text) {
        let dep = SOURCES
            .iter()
            .map(|(n, _)| *n)
            .find(|n| *n == dep)
            .ok_or_else(|| ShaderError::Unknown(format!("{dep} (used by {name})")))?;
        append(dep, out, done, active)?;
    }
    active.pop();
    out.push_str(&format!("// ---- shaders/{name} ----\n"));
    out.push_str(text);
    out.push('\n');
    done.push(name);
    Ok(())
}
