//! `cargo xtask fingerprint [--out FILE] [--against FILE]`: every bundled scene rendered with
//! every method on every backend it has, small and with a pass budget (which makes each
//! render a pure function of its seed), and a hash of each image's pixels, layers included.
//!
//! It is the check that a change meant to move code, not numbers (a refactor of the render
//! loop, the command line or the kernels), left every image bit for bit as it was: write the
//! fingerprints before the change with `--out`, compare after it with `--against`. Timing
//! fields in the EXR header differ from run to run, so the pixels are hashed, not the files.
use anyhow::{Context, Result, bail};
use beamlight_render::{accum::Fnv1a, output::read_exr_layers};
use std::path::Path;
use std::process::Command;

/// Image size and pass budget: enough for every estimator to run all its parts (light
/// paths, caustics, radius shrinking over passes); `auto` gets more rounds, enough for `vbl`
/// to be weighed in ([`beamlight_render::auto::MIN_VBL_PASSES`]).
const SIZE: u32 = 24;
const PASSES: u32 = 3;
const AUTO_ROUNDS: u32 = 5;
const METHODS: [&str; 5] = ["pt", "vrl", "vrl-clamped", "vbl", "auto"];

pub fn main(root: &Path, args: &[String]) -> Result<()> {
    let (mut out, mut against) = (None, None);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => out = it.next().cloned(),
            "--against" => against = it.next().cloned(),
            other => bail!("fingerprint: unknown argument '{other}' (--out FILE, --against FILE)"),
        }
    }
    const _: () = assert!(AUTO_ROUNDS > beamlight_render::auto::MIN_VBL_PASSES as u32);
    crate::build_release_binary(root)?;
    let bin = root.join("target/release/beamlight");
    let work = tempfile_dir()?;
    let mut scenes: Vec<String> = std::fs::read_dir(root.join("assets/scenes"))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        // CARS at any size loads 2 GB of cars; `cars_small` is the same generator.
        .filter(|n| n != "cars.toml")
        .collect();
    scenes.sort();
    let mut lines = Vec::new();
    for scene in &scenes {
        for method in METHODS {
            let backends: &[&str] = if method == "pt" { &["cpu"] } else { &["cpu", "gpu"] };
            for backend in backends {
                // `pt` writes its beauty from unsplit paths unless the components are asked for.
                let splits: &[bool] = if method == "pt" { &[false, true] } else { &[true] };
                for &components in splits {
                    let name = format!(
                        "{} {method}{} {backend}",
                        scene.trim_end_matches(".toml"),
                        if method == "pt" && components {
                            "+components"
                        } else {
                            ""
                        }
                    );
                    let exr = work.join("image.exr");
                    let mut cmd = Command::new(&bin);
                    cmd.arg("render")
                        .arg(root.join("assets/scenes").join(scene))
                        .arg("-o")
                        .arg(&exr)
                        .args(["--method", method, "--backend", backend, "--seed", "7"])
                        .args(["--width", &SIZE.to_string(), "--height", &SIZE.to_string()])
                        .args([
                            "--passes",
                            &if method == "auto" { AUTO_ROUNDS } else { PASSES }.to_string(),
                        ]);
                    if components {
                        cmd.arg("--components");
                    }
                    let output = cmd.output().with_context(|| format!("running {cmd:?}"))?;
                    if !output.status.success() {
                        bail!("{name}: {}", String::from_utf8_lossy(&output.stderr));
                    }
                    let mut hash = Fnv1a::default();
                    for (layer, image) in read_exr_layers(&exr)? {
                        hash.write(layer.as_bytes());
                        for p in &image.pixels {
                            hash.write_f32s(&[p[0], p[1], p[2]]);
                        }
                    }
                    let line = format!("{name} {:016x}", hash.0);
                    println!("{line}");
                    lines.push(line);
                }
            }
        }
    }
    let text = lines.join("\n") + "\n";
    if let Some(path) = out {
        std::fs::write(&path, &text).with_context(|| format!("writing {path}"))?;
    }
    if let Some(path) = against {
        let before = std::fs::read_to_string(&path).with_context(|| format!("reading {path}"))?;
        let changed: Vec<String> = before
            .lines()
            .zip(text.lines())
            .filter(|(a, b)| a != b)
            .map(|(a, b)| format!("  before: {a}\n  now:    {b}"))
            .collect();
        if before.lines().count() != lines.len() {
            bail!(
                "{path} has {} renders, this run {}",
                before.lines().count(),
                lines.len()
            );
        }
        if !changed.is_empty() {
            bail!(
                "{} of {} images changed:\n{}",
                changed.len(),
                lines.len(),
                changed.join("\n")
            );
        }
        println!("all {} images bit for bit as in {path}", lines.len());
    }
    Ok(())
}

/// A fresh directory under the system's temporary one for the renders.
fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("beamlight-fingerprint-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}
