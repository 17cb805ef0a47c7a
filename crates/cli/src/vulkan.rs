//! A quiet Vulkan loader (which device runs the gathers is `beamlight_render::backend`).
use std::path::PathBuf;

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" on every device
/// open without that variable (containers, CI), which reads like one of ours: give the process
/// a private runtime directory when it has none (returned, to be removed at exit).
pub(crate) fn quiet_vulkan_loader() -> Option<PathBuf> {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("beamlight-runtime-{}", std::process::id()));
    #[cfg(unix)]
    let made = {
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new().mode(0o700).create(&dir).is_ok()
    };
    #[cfg(not(unix))]
    let made = std::fs::create_dir(&dir).is_ok();
    if !made {
        return None;
    }
    // SAFETY: called first thing in `main`, before any thread exists.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    Some(dir)
}
