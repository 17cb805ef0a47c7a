//! The reference images: the path tracer run long, in two independent halves (different
//! seeds), cached in `bench/cache/` under a key hashed from the scene's files and the settings.
//!
//! The halves give the reference's own error: for independent unbiased estimates with
//! per-pixel variance σ², the mean of the two has variance σ²/2 and the difference 2σ², so
//! relMSE(reference, truth) ≈ relMSE(half A, half B) / 4 (with the denominator taken at the
//! reference, as the metric does). Every measured error includes this floor.
use super::metrics::{self, Image};
use super::runs::{BeamlightRun, Budget};
use anyhow::{Context, Result, bail};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// What a reference is made with; all of it is part of the cache key.
#[derive(Clone, Debug, PartialEq)]
pub struct RefSettings {
    pub size: u32,
    /// Wall seconds per half (`--time`).
    pub seconds_per_half: f64,
    pub seeds: [u32; 2],
    /// Identifies the renderer (the last commit that touched its sources, plus "dirty" for
    /// uncommitted changes): a changed path tracer makes new references.
    pub renderer: String,
}

impl RefSettings {
    fn describe(&self) -> String {
        format!(
            "pt --components size={} seconds_per_half={} seeds={:?} renderer={}",
            self.size, self.seconds_per_half, self.seeds, self.renderer
        )
    }
}

/// The scene's TOML and every file it refers to: any string value naming an existing file
/// beside it (glTF, grids), and a `.gltf`'s external buffers and images.
pub fn scene_files(scene: &Path) -> Result<Vec<PathBuf>> {
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut files = vec![scene.to_path_buf()];
    let text = std::fs::read_to_string(scene).with_context(|| format!("reading {}", scene.display()))?;
    if scene.extension().is_some_and(|e| e == "toml") {
        let value: toml::Value = toml::from_str(&text).with_context(|| format!("parsing {}", scene.display()))?;
        let mut strings = Vec::new();
        collect_strings(&value, &mut strings);
        for s in strings {
            let p = dir.join(&s);
            if p.is_file() && !files.contains(&p) {
                files.push(p);
            }
        }
    }
    for f in files.clone() {
        if f.extension().is_some_and(|e| e == "gltf") {
            let json: Value =
                serde_json::from_slice(&std::fs::read(&f)?).with_context(|| format!("parsing {}", f.display()))?;
            let gdir = f.parent().unwrap_or(Path::new("."));
            for list in ["buffers", "images"] {
                for item in json[list].as_array().into_iter().flatten() {
                    if let Some(uri) = item["uri"].as_str().filter(|u| !u.starts_with("data:")) {
                        files.push(gdir.join(uri));
                    }
                }
            }
        }
    }
    Ok(files)
}

fn collect_strings(v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::String(s) => out.push(s.clone()),
        toml::Value::Array(a) => a.iter().for_each(|x| collect_strings(x, out)),
        toml::Value::Table(t) => t.values().for_each(|x| collect_strings(x, out)),
        _ => {}
    }
}

/// The cache key: a hash of the contents of every scene file and of the settings.
pub fn cache_key(scene: &Path, settings: &RefSettings) -> Result<String> {
    let mut h = beamlight_render::accum::Fnv1a::default();
    for f in scene_files(scene)? {
        let bytes = std::fs::read(&f).with_context(|| format!("reading {}", f.display()))?;
        h.write(f.file_name().map(|n| n.as_encoded_bytes()).unwrap_or_default());
        h.write(&(bytes.len() as u64).to_le_bytes());
        h.write(&bytes);
    }
    h.write(settings.describe().as_bytes());
    Ok(format!("{:016x}", h.0))
}

/// A loaded reference.
pub struct Reference {
    pub dir: PathBuf,
    pub beauty: Image,
    /// Component layers (`direct`, `Lsm`, …) of the merged reference.
    pub layers: Vec<(String, Image)>,
    pub spp: u64,
    pub seconds: f64,
    /// relMSE between the halves, and the estimate of the merged reference's own relMSE.
    pub halves_rel_mse: f64,
    pub est_rel_mse: f64,
    /// The same per component layer (name, estimated relMSE of the merged reference layer).
    pub layer_est_rel_mse: Vec<(String, f64)>,
    pub reused: bool,
}

/// The cache entry for this scene and these settings, if it exists and matches.
pub fn cached(cache: &Path, scene: &Path, settings: &RefSettings) -> Result<Option<(PathBuf, Value)>> {
    let key = cache_key(scene, settings)?;
    let dir = entry_dir(cache, scene, &key);
    let meta = dir.join("meta.json");
    let Ok(bytes) = std::fs::read(&meta) else {
        return Ok(None);
    };
    let value: Value = serde_json::from_slice(&bytes).with_context(|| format!("parsing {}", meta.display()))?;
    let complete = value["key"].as_str() == Some(key.as_str())
        && ["half_a.exr", "half_b.exr"].iter().all(|f| dir.join(f).is_file());
    Ok(complete.then_some((dir, value)))
}

fn entry_dir(cache: &Path, scene: &Path, key: &str) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    cache.join(format!("{stem}-{key}"))
}

/// Makes the reference of `scene` (or reuses the cached one).
pub fn make_or_reuse(bin: &Path, cache: &Path, scene: &Path, settings: &RefSettings) -> Result<Reference> {
    let (dir, meta, reused) = match cached(cache, scene, settings)? {
        Some((dir, meta)) => (dir, meta, true),
        None => {
            let key = cache_key(scene, settings)?;
            let dir = entry_dir(cache, scene, &key);
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            let mut halves = Vec::new();
            for (half, seed) in ["half_a", "half_b"].iter().zip(settings.seeds) {
                eprintln!(
                    "bench: reference {} {half}: pt for {} s",
                    scene.display(),
                    settings.seconds_per_half
                );
                let t = BeamlightRun {
                    bin,
                    scene,
                    output: dir.join(format!("{half}.exr")),
                    method: "pt",
                    backend: "cpu",
                    budget: Budget::Seconds(settings.seconds_per_half),
                    seed,
                    size: settings.size,
                    components: true,
                }
                .run()?;
                halves.push(json!({"spp": t.passes, "wall_seconds": t.wall, "render_seconds": t.render, "seed": seed}));
            }
            let meta = json!({
                "key": key,
                "scene": scene.display().to_string(),
                "files": scene_files(scene)?.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
                "settings": settings.describe(),
                "halves": halves,
            });
            std::fs::write(dir.join("meta.json"), serde_json::to_string_pretty(&meta)?)?;
            (dir, meta, false)
        }
    };
    let (a, la) = metrics::read_beauty_and_layers(&dir.join("half_a.exr"))?;
    let (b, lb) = metrics::read_beauty_and_layers(&dir.join("half_b.exr"))?;
    let spp = |i: usize| meta["halves"][i]["spp"].as_u64().unwrap_or(1);
    let (na, nb) = (spp(0), spp(1));
    let (wa, wb) = (na as f64 / (na + nb) as f64, nb as f64 / (na + nb) as f64);
    let beauty = metrics::blend(&a, wa, &b, wb)?;
    // relMSE(A, B) with B's denominators; the merged reference's error is about a quarter of
    // the halves' when they have equal sample counts (in general wa²·eA + wb²·eB ≈ that).
    let est = |x: &Image, y: &Image| -> Result<(f64, f64)> {
        let halves = metrics::rel_mse(x, y)?;
        Ok((halves, halves * (wa * wa + wb * wb) / 2.0))
    };
    let (halves_rel_mse, est_rel_mse) = est(&a, &b)?;
    let mut layers = Vec::new();
    let mut layer_est = Vec::new();
    for ((name, x), (name_b, y)) in la.iter().zip(&lb) {
        if name != name_b {
            bail!("reference halves have different layers ({name} vs {name_b})");
        }
        layer_est.push((name.clone(), est(x, y)?.1));
        layers.push((name.clone(), metrics::blend(x, wa, y, wb)?));
    }
    metrics::write_exr(&dir.join("reference.exr"), &beauty)?;
    let seconds = (0..2)
        .map(|i| meta["halves"][i]["wall_seconds"].as_f64().unwrap_or(0.0))
        .sum();
    Ok(Reference {
        dir,
        beauty,
        layers,
        spp: na + nb,
        seconds,
        halves_rel_mse,
        est_rel_mse,
        layer_est_rel_mse: layer_est,
        reused,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> RefSettings {
        RefSettings {
            size: 32,
            seconds_per_half: 10.0,
            seeds: [1, 2],
            renderer: "abc".into(),
        }
    }

    #[test]
    fn cache_key_follows_the_scene_files_and_settings() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("s.toml");
        std::fs::write(
            &scene,
            "gltf = \"s.gltf\"\n[[media]]\ndensity = { grid = \"g.bgrid\" }\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("s.gltf"), r#"{"buffers": [{"uri": "s.bin"}]}"#).unwrap();
        std::fs::write(dir.path().join("s.bin"), [1u8, 2, 3]).unwrap();
        std::fs::write(dir.path().join("g.bgrid"), [0u8; 8]).unwrap();
        let files = scene_files(&scene).unwrap();
        assert_eq!(files.len(), 4, "{files:?}");
        let k0 = cache_key(&scene, &settings()).unwrap();
        assert_eq!(k0, cache_key(&scene, &settings()).unwrap(), "the key is deterministic");
        // Any referenced file, the TOML itself, or a setting changes the key.
        std::fs::write(dir.path().join("s.bin"), [1u8, 2, 4]).unwrap();
        let k1 = cache_key(&scene, &settings()).unwrap();
        assert_ne!(k0, k1);
        std::fs::write(dir.path().join("g.bgrid"), [1u8; 8]).unwrap();
        let k2 = cache_key(&scene, &settings()).unwrap();
        assert_ne!(k1, k2);
        let k3 = cache_key(
            &scene,
            &RefSettings {
                seconds_per_half: 20.0,
                ..settings()
            },
        )
        .unwrap();
        assert_ne!(k2, k3);
        let k4 = cache_key(&scene, &RefSettings { size: 64, ..settings() }).unwrap();
        assert_ne!(k2, k4);
        let k5 = cache_key(
            &scene,
            &RefSettings {
                renderer: "def".into(),
                ..settings()
            },
        )
        .unwrap();
        assert_ne!(k2, k5);
        // A cache entry written under the old key is not found for the new one.
        let cache = dir.path().join("cache");
        let entry = entry_dir(&cache, &scene, &k2);
        std::fs::create_dir_all(&entry).unwrap();
        for f in ["half_a.exr", "half_b.exr"] {
            std::fs::write(entry.join(f), b"x").unwrap();
        }
        std::fs::write(entry.join("meta.json"), json!({"key": k2}).to_string()).unwrap();
        assert!(cached(&cache, &scene, &settings()).unwrap().is_some());
        std::fs::write(&scene, "gltf = \"s.gltf\"\n# edited\n").unwrap();
        assert!(cached(&cache, &scene, &settings()).unwrap().is_none());
        assert!(
            cached(&cache, &scene, &RefSettings { size: 64, ..settings() })
                .unwrap()
                .is_none()
        );
    }
}
