//! Running the renderers as subprocesses and timing them: wall time around the process (so
//! start-up is included, for every renderer alike) and the renderer's own account of its time
//! without start-up (`beamlight render --stats-json`, the Mitsuba driver's JSON).
use anyhow::{Context, Result, bail};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// How long a render may run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Wall seconds, start-up included (`--time`).
    Seconds(f64),
}

/// One finished render.
#[derive(Clone, Debug)]
pub struct Timing {
    /// Wall time around the whole process, start-up included.
    pub wall: f64,
    /// The renderer's own time without start-up (scene loading, BVH, device, JIT).
    pub render: f64,
    /// Passes (many-light methods) or samples per pixel (path tracers).
    pub passes: u64,
    /// The renderer's JSON record (`--stats-json` or the Mitsuba driver's).
    pub stats: Value,
}

/// What to render with beamlight.
pub struct BeamlightRun<'a> {
    pub bin: &'a Path,
    pub scene: &'a Path,
    pub output: PathBuf,
    pub method: &'a str,
    pub backend: &'a str,
    pub budget: Budget,
    pub seed: u32,
    pub size: u32,
    pub components: bool,
    /// More options, after the ones above.
    pub extra_args: &'a [&'a str],
}

impl BeamlightRun<'_> {
    pub fn run(&self) -> Result<Timing> {
        let json = self.output.with_extension("json");
        let mut cmd = Command::new(self.bin);
        cmd.arg("render")
            .arg(self.scene)
            .arg("-o")
            .arg(&self.output)
            .args(["--method", self.method, "--backend", self.backend])
            .args(["--seed", &self.seed.to_string()])
            .args(["--width", &self.size.to_string(), "--height", &self.size.to_string()])
            .arg("--stats-json")
            .arg(&json);
        let Budget::Seconds(s) = self.budget;
        cmd.args(["--time", &format!("{s}")]);
        if self.components {
            cmd.arg("--components");
        }
        cmd.args(self.extra_args);
        let wall = timed(&mut cmd)?;
        let stats: Value =
            serde_json::from_slice(&std::fs::read(&json).with_context(|| format!("reading {}", json.display()))?)
                .with_context(|| format!("parsing {}", json.display()))?;
        Ok(Timing {
            wall,
            render: stats["render_seconds"].as_f64().unwrap_or(f64::NAN),
            passes: stats["passes"].as_u64().unwrap_or(0),
            stats,
        })
    }
}

/// Runs `cmd` (output captured, shown on failure) and returns its wall time in seconds.
pub fn timed(cmd: &mut Command) -> Result<f64> {
    let clock = Instant::now();
    let out = cmd.output().with_context(|| format!("running {cmd:?}"))?;
    let wall = clock.elapsed().as_secs_f64();
    if !out.status.success() {
        bail!(
            "{cmd:?} failed ({}):\n{}{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(wall)
}

/// The median of `v` (mean of the middle two for an even count); NaN when empty.
pub fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(super::median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(super::median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(super::median(&[]).is_nan());
    }
}
