//! Long and split renders on the command line: pass ranges (`--passes A..B`), checkpoints
//! (`--checkpoint`, `--resume`), `beamlight merge`, and Ctrl-C.
use anyhow::{Context, Result, bail};
use beamlight_render::{RenderOptions, accum::Accumulators};
use beamlight_scene::Scene;
use std::{
    path::{Path, PathBuf},
    sync::atomic::{AtomicBool, Ordering},
};

/// `--passes`: a count, or a range `A..B` of the global pass sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassRange {
    pub start: Option<u64>,
    pub end: u64,
}

impl std::str::FromStr for PassRange {
    type Err = String;
    fn from_str(s: &str) -> Result<PassRange, String> {
        let number = |t: &str| {
            t.trim()
                .parse::<u64>()
                .map_err(|_| format!("`{s}` is not a pass count N or a range A..B"))
        };
        match s.split_once("..") {
            None => Ok(PassRange {
                start: None,
                end: number(s)?,
            }),
            Some((a, b)) => {
                let (a, b) = (number(a)?, number(b)?);
                if a >= b {
                    return Err(format!("the pass range {a}..{b} is empty"));
                }
                Ok(PassRange { start: Some(a), end: b })
            }
        }
    }
}

/// What decides a pass, as one line: the scene's content (geometry, materials, media with
/// their grids, lights, camera), the method, the image size, the seed and every estimator
/// setting. Accumulators continue or combine only with the same fingerprint.
pub fn fingerprint(scene: &Scene, opts: &RenderOptions) -> String {
    let mut h = beamlight_render::accum::Fnv1a::default();
    for t in &scene.triangles {
        h.write_f32s(&t.p.iter().flat_map(|p| p.to_array()).collect::<Vec<_>>());
        h.write(&t.material.to_le_bytes());
        h.write(format!("{:?}{:?}{:?}", t.n, t.uv, t.interface).as_bytes());
    }
    h.write(format!("{:?}", scene.materials).as_bytes());
    for m in &scene.media {
        h.write(format!("{} {:?} {:?} {}", m.name, m.sigma_s, m.sigma_a, m.g).as_bytes());
        if let Some(g) = &m.density {
            h.write(format!("{:?} {:?} {:?}", g.res, g.lo, g.hi).as_bytes());
            h.write_f32s(&g.values);
        }
    }
    h.write(format!("{:?} {:?} {:?}", scene.global_medium, scene.lights, scene.camera).as_bytes());
    // A texture's Debug names it and gives its size, wrap modes and brightest texel.
    h.write(format!("{:?}", scene.textures).as_bytes());
    format!(
        "scene {:016x}; {} {}x{}; seed {}; components {}; {:?}; {:?}",
        h.0,
        opts.method.name(),
        opts.width,
        opts.height,
        opts.seed,
        opts.components,
        opts.path_tracer,
        opts.many_lights
    )
}

/// Where a pass range's accumulators go without `--checkpoint`: beside the image.
pub fn default_accum_path(output: &Path) -> PathBuf {
    output.with_extension("accum")
}

/// Reads a checkpoint for `--resume`, refusing one from another scene or other settings.
pub fn read_checkpoint(path: &Path, fingerprint: &str) -> Result<Accumulators> {
    let acc = Accumulators::read(path)?;
    if acc.fingerprint != fingerprint {
        bail!(
            "{}: the checkpoint was written by a different render (scene or settings differ):\n  checkpoint: {}\n  this run:   {}",
            path.display(),
            acc.fingerprint,
            fingerprint
        );
    }
    Ok(acc)
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// A render stopped by Ctrl-C (after writing its image): exit code 130.
#[derive(Debug, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;

/// Ctrl-C finishes the current pass and writes the image; a second Ctrl-C quits at once.
pub fn catch_interrupts() {
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted twice: quitting without writing");
            std::process::exit(130);
        }
        eprintln!("\ninterrupted: finishing the current pass, then writing the image (Ctrl-C again to quit now)");
    });
}

pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// `beamlight merge`: accumulators of adjacent pass ranges → one image (and accumulators).
/// `expected` (`merge --passes`) is the range the parts must cover; without it, the span from
/// the first part's start to the last one's end (a missing last range then goes unnoticed).
/// Prints which ranges are present and which are missing; an incomplete set is refused.
pub fn merge(
    parts: &[PathBuf],
    expected: Option<PassRange>,
    output: &Path,
    preview: Option<&Path>,
    exposure: f32,
) -> Result<()> {
    if parts.is_empty() {
        bail!("merge: name the accumulator files of the pass ranges to merge");
    }
    let mut read = Vec::new();
    for p in parts {
        read.push((p.clone(), Accumulators::read(p)?));
    }
    let expected = expected.map(|r| r.start.unwrap_or(0)..r.end);
    let (merged, coverage) = Accumulators::merge(read, expected).map_err(|e| anyhow::anyhow!("merge: {e}"))?;
    eprintln!("pass ranges:\n{coverage}");
    let metadata = [
        ("beamlight.first_pass", merged.first_pass.to_string()),
        ("beamlight.fingerprint", merged.fingerprint.clone()),
    ];
    let image =
        beamlight_render::output::write_films(output, &merged.film, &merged.components, &merged.discarded, &metadata)?;
    if let Some(p) = preview {
        beamlight_render::output::write_png(p, &image, exposure)?;
    }
    let accum = default_accum_path(output);
    merged
        .write(&accum)
        .with_context(|| "writing the merged accumulators")?;
    eprintln!(
        "merged passes {}..{} from {} files -> {} (accumulators: {})",
        merged.first_pass,
        merged.end_pass(),
        parts.len(),
        output.display(),
        accum.display()
    );
    Ok(())
}
