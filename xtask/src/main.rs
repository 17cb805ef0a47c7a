//! `cargo xtask …`: project chores that are code, not shell scripts.
//!
//! * `assets [--check]`: (re)generate the bundled scenes in `assets/scenes/`, including the
//!   large ones that are not committed (`cars.glb`); with `--check`, only verify that the
//!   committed files are exactly what the generator writes.
//! * `bad-scenes [--check]`: the same for the generated files of the broken-scene corpus in
//!   `tests/bad_scenes/`.
//! * `ci`: make sure Mesa lavapipe is installed (apt-get, when missing), check the generated
//!   files, write the large uncommitted ones, then run the whole test suite in release mode.
//! * `fuzz [SECONDS]`: coverage-guided fuzzing of scene loading (`fuzz/`, cargo-fuzz with
//!   libFuzzer), each target for SECONDS (default 60), seeded with the broken-scene corpus;
//!   installs cargo-fuzz when missing. Crashes land in `fuzz/artifacts/`: make each one a case
//!   in `tests/bad_scenes/`.
//! * `stress`: the numerical stress grid (`tests/stress.rs`) at full size (larger images, more
//!   passes): minutes, not part of CI.
//! * `bench [OPTIONS]`: run time against error for every method and backend and for Mitsuba 3,
//!   against cached path-traced references (`xtask/src/bench/`, `docs/benchmarks.md`).
//! * `fingerprint [--out FILE] [--against FILE]`: every bundled scene at 24² and 3 passes with
//!   every method and backend, one hash of each image's pixels; `--against` fails on any image
//!   that is not bit for bit the same as before (for changes that should move no number).
//! * `cluster [--keep]`: split renders on a one-node Slurm cluster started on this machine
//!   (installs slurm-wlm and munge with apt-get when missing): the README's job-array script,
//!   merged and compared bit for bit with a one-go render; a cancelled task refused by `merge`
//!   and resubmitted (`xtask/src/cluster.rs`).
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::process::Command;

mod assets;
mod bad_scenes;
mod bench;
mod cluster;
mod fingerprint;
mod glass_scenes;
/// Checked by its tests, in the normal test run.
#[cfg(test)]
mod imports;
mod showcase;

const USAGE: &str = "usage: cargo xtask <command>

commands:
  assets [--check]      write the bundled scenes to assets/scenes/ (--check: verify only)
  bad-scenes [--check]  write the generated broken-scene fixtures to tests/bad_scenes/
  ci                    install lavapipe if missing, check generated files, run all tests
  stress                the numerical stress grid (tests/stress.rs) at full size
  fuzz [SECONDS]        fuzz the scene loaders (fuzz/), each target for SECONDS (60)
  bench [OPTIONS]       run time against error per scene and method (bench --help)
  cluster [--keep]      split render on a one-node Slurm cluster (apt-installs slurm-wlm, munge)
  fingerprint [--out F] [--against F]
                        hash every bundled scene's image per method and backend (bit-identity)";

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().is_some_and(|a| a == "fuzz") {
        let seconds = match args.get(1) {
            Some(s) => s
                .parse()
                .with_context(|| format!("fuzz: '{s}' is not a number of seconds"))?,
            None => 60u64,
        };
        return fuzz(seconds);
    }
    if args.first().is_some_and(|a| a == "bench") {
        return bench::main(&root(), &args[1..]);
    }
    if args.first().is_some_and(|a| a == "fingerprint") {
        return fingerprint::main(&root(), &args[1..]);
    }
    if args.first().is_some_and(|a| a == "cluster") {
        return cluster::main(&root(), &args[1..]);
    }
    let check = args.iter().skip(1).any(|a| a == "--check");
    if let Some(extra) = args.iter().skip(1).find(|a| *a != "--check") {
        bail!("unknown argument '{extra}'\n\n{USAGE}");
    }
    match args.first().map(String::as_str) {
        Some("assets") if check => sync(&assets::files(), true),
        Some("assets") => sync(&assets::files(), false).and_then(|()| sync(&showcase::large_files(), false)),
        Some("bad-scenes") => sync(&bad_scenes::files(), check),
        Some("ci") => ci(),
        Some("stress") => run_tests(
            test_command()?
                .args(["test", "--release", "--test", "stress"])
                .env("BEAMLIGHT_STRESS", "full"),
        ),
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}");
            Ok(())
        }
        Some(other) => bail!("unknown command '{other}'\n\n{USAGE}"),
        None => bail!("{USAGE}"),
    }
}

/// Builds `target/release/beamlight` (what the bench and the fingerprints run).
fn build_release_binary(root: &Path) -> Result<()> {
    eprintln!("building the release binary");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    run(Command::new(cargo).current_dir(root).args([
        "build",
        "--release",
        "--quiet",
        "--package",
        "beamlight",
        "--bin",
        "beamlight",
    ]))
}

/// The workspace root (the parent of this crate's directory).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

/// Writes `files` under the workspace root, or with `check` only compares them.
fn sync(files: &[(String, Vec<u8>)], check: bool) -> Result<()> {
    let root = root();
    let mut stale = Vec::new();
    for (rel, bytes) in files {
        let path = root.join(rel);
        let current = std::fs::read(&path).ok();
        if current.as_deref() == Some(bytes.as_slice()) {
            continue;
        }
        if check {
            stale.push(rel.clone());
        } else {
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            }
            std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
            println!("wrote {rel} ({} bytes)", bytes.len());
        }
    }
    if !stale.is_empty() {
        bail!(
            "out of date (run `cargo xtask assets` / `cargo xtask bad-scenes`): {}",
            stale.join(", ")
        );
    }
    if check {
        println!("{} generated files up to date", files.len());
    }
    Ok(())
}

const LAVAPIPE_ICD: &str = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json";

fn run(cmd: &mut Command) -> Result<()> {
    eprintln!("+ {cmd:?}");
    let status = cmd.status().with_context(|| format!("running {cmd:?}"))?;
    if !status.success() {
        bail!("{cmd:?} failed: {status}");
    }
    Ok(())
}

fn ci() -> Result<()> {
    if !Path::new(LAVAPIPE_ICD).exists() {
        eprintln!("Mesa lavapipe not found ({LAVAPIPE_ICD}); installing mesa-vulkan-drivers with apt-get");
        let is_root = Command::new("id")
            .arg("-u")
            .output()
            .map(|o| o.stdout.starts_with(b"0"))
            .unwrap_or(false);
        let apt = |args: &[&str]| {
            let mut c = if is_root {
                Command::new("apt-get")
            } else {
                Command::new("sudo")
            };
            if !is_root {
                c.arg("apt-get");
            }
            c.args(args).env("DEBIAN_FRONTEND", "noninteractive");
            c
        };
        run(&mut apt(&["update"]))?;
        run(&mut apt(&[
            "install",
            "-y",
            "--no-install-recommends",
            "mesa-vulkan-drivers",
        ]))?;
    }
    sync(&assets::files(), true)?;
    sync(&bad_scenes::files(), true)?;
    // The large showcase meshes are not committed: make them (or refresh them) for the tests.
    sync(&showcase::large_files(), false)?;
    let mut tests = test_command()?;
    tests
        .args(["test", "--release", "--workspace", "--no-fail-fast"])
        // lavapipe was just ensured: a GPU test that finds no adapter must fail, not skip.
        .env("CI", "true");
    run_tests(&mut tests)
}

/// `cargo` in the repository root, with a private XDG_RUNTIME_DIR when there is none (Mesa's
/// Vulkan loader complains on every device open without one).
fn test_command() -> Result<Command> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut c = Command::new(cargo);
    c.current_dir(root());
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        let dir = std::env::temp_dir().join("beamlight-xdg-runtime");
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700))?;
        }
        c.env("XDG_RUNTIME_DIR", dir);
    }
    Ok(c)
}

/// `cargo xtask fuzz`: each fuzz target for `seconds`, seeded with the broken-scene corpus.
fn fuzz(seconds: u64) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let have_fuzz = Command::new(&cargo)
        .args(["fuzz", "--version"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !have_fuzz {
        run(Command::new(&cargo).args(["install", "cargo-fuzz", "--locked"]))?;
    }
    let fuzz_dir = root().join("fuzz");
    let bad = root().join("tests/bad_scenes");
    for (target, exts) in [("scene_toml", &["toml"][..]), ("gltf", &["gltf", "glb"][..])] {
        let corpus = fuzz_dir.join("corpus").join(target);
        std::fs::create_dir_all(&corpus)?;
        for entry in std::fs::read_dir(&bad)? {
            let path = entry?.path();
            if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| exts.contains(&e))
            {
                std::fs::copy(&path, corpus.join(path.file_name().expect("a file")))?;
            }
        }
        // The stable toolchain accepts cargo-fuzz's -Z flags with RUSTC_BOOTSTRAP; without a
        // sanitizer libFuzzer still catches panics, and Rust needs no ASan for memory safety.
        run(Command::new(&cargo)
            .current_dir(&fuzz_dir)
            .env("RUSTC_BOOTSTRAP", "1")
            .args([
                "fuzz",
                "run",
                "--sanitizer",
                "none",
                target,
                corpus.to_str().expect("UTF-8 path"),
            ])
            .args(["--", &format!("-max_total_time={seconds}")]))?;
    }
    Ok(())
}

/// Runs `cargo test`, passing its output through, and ends with one line totalling every test
/// binary's results (cargo itself ends on whichever binary ran last, often a doc-test with none).
fn run_tests(cmd: &mut Command) -> Result<()> {
    use std::io::{BufRead, BufReader};
    eprintln!("+ {cmd:?}");
    let mut child = cmd
        .stdout(std::process::Stdio::piped())
        .spawn()
        .with_context(|| format!("running {cmd:?}"))?;
    let (mut passed, mut failed) = (0u64, 0u64);
    for line in BufReader::new(child.stdout.take().expect("piped stdout")).lines() {
        let line = line?;
        println!("{line}");
        if let Some(rest) = line.strip_prefix("test result: ") {
            passed += count_before(rest, " passed");
            failed += count_before(rest, " failed");
        }
    }
    let status = child.wait()?;
    println!("tests: {passed} passed, {failed} failed");
    if !status.success() {
        bail!("{cmd:?} failed: {status}");
    }
    Ok(())
}

/// The number just before `label` in a cargo test summary ("ok. 12 passed; 0 failed; …").
fn count_before(summary: &str, label: &str) -> u64 {
    summary
        .split(';')
        .find_map(|part| {
            part.trim()
                .trim_start_matches("ok. ")
                .trim_start_matches("FAILED. ")
                .strip_suffix(label.trim_start())
        })
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The committed assets and fixtures are exactly what the generators write.
    #[test]
    fn generated_files_are_committed_and_up_to_date() {
        for (rel, bytes) in assets::files().iter().chain(bad_scenes::files().iter()) {
            let on_disk = std::fs::read(root().join(rel)).unwrap_or_default();
            assert!(
                on_disk == *bytes,
                "{rel} differs from the generator's output; run `cargo xtask assets` and `cargo xtask bad-scenes`"
            );
        }
    }

    #[test]
    fn test_summaries_are_counted() {
        let line = "ok. 12 passed; 3 failed; 0 ignored; 0 measured; 0 filtered out; finished in 0.1s";
        assert_eq!((count_before(line, " passed"), count_before(line, " failed")), (12, 3));
        assert_eq!(count_before("FAILED. 1 passed; 2 failed; 0 ignored", " failed"), 2);
    }

    #[test]
    fn generation_is_deterministic() {
        assert_eq!(assets::files(), assets::files());
        assert_eq!(bad_scenes::files(), bad_scenes::files());
    }
}
