//! The `beamlight` command; everything lives in `beamlight-cli`.
fn main() -> std::process::ExitCode {
    beamlight_cli::main()
}
