//! Mitsuba 3 as a peer: the scene exported by `beamlight export-mitsuba`, rendered by
//! `bench/mitsuba_render.py` (its `volpath`) for the same wall-time budgets.
use super::runs::{self, Budget, Timing};
use anyhow::{Context, Result};
use std::path::Path;
use std::process::Command;

pub const INSTALL_HINT: &str = "pip install mitsuba (and, for the fast llvm_ad_rgb variant, apt-get install libllvm19)";

/// `Ok(version)` when the `mitsuba` Python package imports, else why not.
pub fn available(python: &str) -> Result<String, String> {
    let out = Command::new(python)
        .args(["-c", "import mitsuba; print(mitsuba.__version__)"])
        .output()
        .map_err(|e| format!("cannot run {python}: {e}"))?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
    } else {
        Err(format!(
            "the Python package `mitsuba` is not installed ({INSTALL_HINT})"
        ))
    }
}

/// Exports `scene` at `size`² to `xml`; returns what the exporter could not express exactly.
pub fn export(bin: &Path, scene: &Path, xml: &Path, size: u32) -> Result<Vec<String>> {
    let out = Command::new(bin)
        .arg("export-mitsuba")
        .arg(scene)
        .arg(xml)
        .args(["--width", &size.to_string(), "--height", &size.to_string()])
        .output()
        .context("running beamlight export-mitsuba")?;
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    if !out.status.success() {
        anyhow::bail!("beamlight export-mitsuba {} failed: {stderr}", scene.display());
    }
    Ok(stderr
        .lines()
        .filter_map(|l| l.strip_prefix("not exported exactly: "))
        .map(str::to_string)
        .collect())
}

/// Renders `xml` with Mitsuba for `budget`, timing the whole Python process.
pub fn render(python: &str, script: &Path, xml: &Path, output: &Path, budget: Budget, seed: u32) -> Result<Timing> {
    let json = output.with_extension("json");
    let mut cmd = Command::new(python);
    cmd.arg(script).arg(xml).arg(output).args(["--seed", &seed.to_string()]);
    let Budget::Seconds(s) = budget;
    cmd.args(["--time", &format!("{s}")]);
    cmd.arg("--json").arg(&json);
    let wall = runs::timed(&mut cmd)?;
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).with_context(|| format!("reading {}", json.display()))?)?;
    Ok(Timing {
        wall,
        render: stats["render_seconds"].as_f64().unwrap_or(f64::NAN),
        passes: stats["spp"].as_u64().unwrap_or(0),
        stats,
    })
}
