//! The `beamlight` command line: `render`, `compare`, `info`, `merge`, `export-mitsuba`.
pub mod mitsuba;
mod runs;

/// `writeln!` into a report string (formatting into a `String` cannot fail).
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}

mod args;
mod info;
mod render;
mod report;
mod tools;
mod vulkan;

use anyhow::{Context, Result, bail};
use args::*;
use clap::Parser;
use info::info;
use render::render;
use std::{path::Path, process::ExitCode, time::Instant};
use tools::{compare_cmd, export_mitsuba, sheet_cmd};
use vulkan::quiet_vulkan_loader;

/// Runs the command line; errors are printed as one clear message and give exit code 1.
pub fn main() -> ExitCode {
    let start = Instant::now();
    let runtime_dir = quiet_vulkan_loader();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(*args, start),
        Command::Compare { a, b, layers } => compare_cmd(&a, &b, layers),
        Command::Info { scene } => info(&scene),
        Command::ExportMitsuba {
            scene,
            output,
            width,
            height,
        } => export_mitsuba(&scene, &output, width, height),
        Command::Sheet {
            inputs,
            labels,
            output,
            columns,
            percentile,
            exposure,
            downsample,
        } => sheet_cmd(&inputs, &labels, &output, columns, percentile, exposure, downsample),
        Command::Merge {
            parts,
            passes,
            output,
            preview,
            exposure,
        } => check_output_path(&output, "exr")
            .and_then(|()| runs::merge(&parts, passes, &output, preview.as_deref(), exposure)),
    };
    if let Some(dir) = runtime_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The image is written; the exit code still tells a script the render did not finish.
        Err(e) if e.is::<runs::Interrupted>() => ExitCode::from(130),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

pub(crate) fn check_output_path(p: &Path, ext: &str) -> Result<()> {
    match p.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case(ext) => Ok(()),
        _ => bail!("{}: output file must end in .{ext}", p.display()),
    }
}

/// Prints a finished report; a closed pipe (`beamlight info … | head`) is not an error.
pub(crate) fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e).context("cannot write to standard output"),
        _ => Ok(()),
    }
}
