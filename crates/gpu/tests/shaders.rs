//! Every WGSL file is compiled in, and every kernel composes and passes naga's validation.
use beamlight_gpu::shaders::{self, SOURCES};
use std::path::{Path, PathBuf};

fn shader_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shaders")
}

fn wgsl_files(dir: &Path, base: &Path, out: &mut Vec<String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            wgsl_files(&path, base, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path.strip_prefix(base).unwrap().to_string_lossy().replace('\\', "/"));
        }
    }
}

#[test]
fn every_file_on_disk_is_compiled_in() {
    let dir = shader_dir();
    let mut on_disk = Vec::new();
    wgsl_files(&dir, &dir, &mut on_disk);
    on_disk.sort();
    let mut listed: Vec<String> = SOURCES.iter().map(|(n, _)| n.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed, "shaders/ and shaders::SOURCES disagree");
    for (name, text) in SOURCES {
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            *text,
            "{name} is stale"
        );
    }
}

/// Composes `name` (a path under `shaders/`), parses and validates it with naga.
fn validated(name: &str) -> naga::Module {
    let source = shaders::compose(name).unwrap();
    let module =
        naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{name}:\n{}", e.emit_to_string(&source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
    module
}

#[test]
fn every_kernel_composes_and_validates() {
    let mut count = 0;
    for name in shaders::kernels() {
        let module = validated(name);
        assert!(
            module.entry_points.iter().any(|e| e.name == "main"),
            "{name} has no main"
        );
        count += 1;
    }
    assert!(count >= 2);
}

#[test]
fn every_library_file_validates_with_what_it_uses() {
    // A library file composed on its own must also be valid WGSL (no hidden dependency on
    // what a kernel happens to include before it).
    // Templates (files with hooks) are checked below, inside their kernels.
    for (name, _) in SOURCES
        .iter()
        .filter(|(n, text)| n.starts_with("lib/") && shaders::hooks(text).next().is_none())
    {
        validated(name);
    }
}

/// A template's hooks are defined by every kernel that uses it (in its own file or in a library
/// file it uses, never in the template), and at least one kernel uses each template.
#[test]
fn every_kernel_defines_the_hooks_of_the_templates_it_uses() {
    for (template, text) in SOURCES.iter().filter(|(_, t)| shaders::hooks(t).next().is_some()) {
        let users: Vec<&str> = shaders::kernels()
            .filter(|k| {
                shaders::compose(k)
                    .unwrap()
                    .contains(&format!("// ---- shaders/{template} ----"))
            })
            .collect();
        assert!(!users.is_empty(), "{template}: no kernel uses it");
        for kernel in users {
            // The kernel's own file or a library it uses (the record hooks shared by the
            // kernels of one record kind) may define a hook; the template itself may not.
            let composed = shaders::compose(kernel).unwrap();
            let own = composed.replace(*text, "");
            for hook in shaders::hooks(text) {
                let defined = ["fn", "struct", "const"].iter().any(|kw| {
                    own.contains(&format!("{kw} {hook}("))
                        || own.contains(&format!("{kw} {hook} "))
                        || own.contains(&format!("{kw} {hook}:"))
                });
                assert!(
                    defined,
                    "{kernel} uses {template} but does not define its hook `{hook}`"
                );
            }
        }
    }
}

#[test]
fn composition_includes_each_file_once_and_dependencies_first() {
    let source = shaders::compose("trace_rays.wgsl").unwrap();
    let order: Vec<&str> = source
        .lines()
        .filter_map(|l| l.strip_prefix("// ---- shaders/"))
        .map(|l| l.trim_end_matches(" ----"))
        .collect();
    assert_eq!(
        order,
        ["lib/scene.wgsl", "lib/geometry.wgsl", "lib/bvh.wgsl", "trace_rays.wgsl"]
    );
    assert!(shaders::compose("lib/nope.wgsl").is_err());
}
