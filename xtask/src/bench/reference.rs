//! The reference images, cached in `bench/cache/` under a key hashed from the scene's files and
//! the settings. Each reference estimator (the path tracer, and for scenes where it converges
//! slowly a second, independent one such as unclamped `vrl`) renders [`PARTS`] independent
//! parts (different seeds), split into two halves.
//!
//! The halves give the reference's own error: for independent unbiased estimates with
//! per-pixel variance σ², the mean of the two has variance σ²/2 and the difference 2σ², so
//! relMSE(reference, truth) ≈ relMSE(half A, half B) / 4 (with the denominator taken at the
//! reference, as the metric does). Every measured error includes this floor.
//!
//! A reference whose own error is above its goal grows in rounds: one estimator at a time
//! renders every part again for as long as all its rounds so far (doubling its time), each
//! round with new seeds and merged into its part by sample counts, so a part stays one
//! independent render. The estimator extended is the one that lowers the combination's
//! error most per second (on `lamp_in_glass` the path tracer's own relMSE is about 10 and
//! unclamped `vrl`'s 1e-2: time given to `pt` there is lost). Rounds stop at the goal or
//! when the next would pass the time cap.
//!
//! With two estimators, they are first checked against each other per component layer
//! ([`CrossCheck`]): the difference of their image means (and of the means of 4 × 4 tiles)
//! against standard errors from the parts' spread (batch means, which stay honest when an
//! estimator's pixels are correlated, as the virtual lights of one pass make them). Then each
//! layer of the reference is their inverse-variance combination, with one weight per layer and
//! estimator, and the beauty is the sum of the combined layers; the halves are combined the same
//! way, so the combination's own error is estimated as a single estimator's is.
use super::metrics::{self, Image};
use super::runs::{BeamlightRun, Budget};
use anyhow::{Context, Result, bail};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// Independent parts per reference estimator (the first half of them make half A).
pub const PARTS: usize = 8;

/// Camera samples per pixel and pass for direct light in a many-light reference part
/// (`--direct-samples`; a render's default is 4). A `vrl` pass at 96² costs about 2 s, so a
/// 15-s part has 8 passes: 32 camera samples per pixel saw the emitter where the camera sees a
/// small light, and on `caustic_sphere` the light's few edge pixels, whose coverage of the
/// light is then binomial noise at radiance 375, made the parts' `direct` 4.5 % brighter than
/// `pt`'s (z = −4.8 from 7-dof errors). 32 a pass cost a `vrl` pass 10 % more and gave those
/// pixels `pt`'s values within 1 % (283 vs 285, summed over the six).
const MANY_LIGHT_DIRECT_SAMPLES: u32 = 32;

/// What a reference is made with; all of it is part of the cache key.
#[derive(Clone, Debug, PartialEq)]
pub struct RefSettings {
    pub size: u32,
    /// Wall seconds per half and estimator (each of the half's parts gets its share).
    pub seconds_per_half: f64,
    /// Seeds of the parts are `seed_base + part`, offset per estimator.
    pub seed_base: u32,
    /// The estimators (`--method`s), the first usually `pt`.
    pub methods: Vec<String>,
    /// Identifies the renderer (the last commit that touched its sources, plus "dirty" for
    /// uncommitted changes): a changed path tracer makes new references.
    pub renderer: String,
    /// The merged reference's own relMSE that ends its rounds (0: rounds until the cap).
    pub goal: f64,
    /// The most wall seconds all rounds of all estimators may take together.
    pub max_seconds: f64,
    /// Components the renders are restricted to (`--only`), for a reference of those alone:
    /// each then gets the whole time, so its own error is far below a whole-image
    /// reference's layer of it.
    pub only: Option<String>,
}

impl RefSettings {
    fn describe(&self) -> String {
        // `only` is appended only when set, so whole-image references keep their keys.
        format!(
            "{} --components parts={PARTS} size={} seconds_per_half={} seed_base={} renderer={} \
             many-light direct samples={MANY_LIGHT_DIRECT_SAMPLES} goal={} max_seconds={}{}",
            self.methods.join("+"),
            self.size,
            self.seconds_per_half,
            self.seed_base,
            self.renderer,
            self.goal,
            self.max_seconds,
            self.only.as_ref().map(|c| format!(" only={c}")).unwrap_or_default()
        )
    }

    /// Wall seconds of an estimator's first `rounds` rounds: 2 × `seconds_per_half`, doubled
    /// by each round after the first.
    fn seconds_of(&self, rounds: usize) -> f64 {
        match rounds {
            0 => 0.0,
            r => 2.0 * self.seconds_per_half * (1u64 << (r - 1).min(40)) as f64,
        }
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
        && settings
            .methods
            .iter()
            .all(|m| (0..PARTS).all(|p| dir.join(format!("{m}_{p}.exr")).is_file()));
    Ok(complete.then_some((dir, value)))
}

fn entry_dir(cache: &Path, scene: &Path, key: &str) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    cache.join(format!("{stem}-{key}"))
}

/// One reference estimator's renders: its parts, merged per half.
pub struct Estimator {
    pub method: String,
    /// Samples per pixel (path tracers) or passes in half A and in half B.
    half_counts: [u64; 2],
    pub seconds: f64,
    /// Half A and half B (beauty, component layers), each the part-weighted mean of its parts.
    halves: [(Image, Vec<(String, Image)>); 2],
    /// Every part's layers (for the batch-means standard errors).
    parts: Vec<Vec<(String, Image)>>,
    /// Its own estimated relMSE (beauty) from its halves.
    pub est_rel_mse: f64,
    /// Rounds rendered (each part's time doubles with every round after the first).
    pub rounds: usize,
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
    /// The estimators it was made from.
    pub estimators: Vec<Estimator>,
    /// With two estimators, their agreement and weights per layer.
    pub cross_check: Vec<CrossCheck>,
}

/// Two reference estimators against each other on one component layer.
#[derive(Clone, Debug)]
pub struct CrossCheck {
    pub layer: String,
    /// Image means (RGB summed / 3) and their standard errors from the parts' spread.
    pub mean: [f64; 2],
    pub se: [f64; 2],
    /// (mean₀ − mean₁) / √(se₀² + se₁²).
    pub z: f64,
    /// Σ z² over the 4 × 4 tiles whose means are not both zero, and how many tiles that is:
    /// about the tile count when the two agree everywhere (with 7-dof standard errors the
    /// expectation is 7/5 of it; a bias confined to part of the image shows here).
    pub tile_chi2: f64,
    pub tiles: usize,
    /// Weight of the first estimator in the combination (inverse estimated variance).
    pub weight0: f64,
}

impl CrossCheck {
    /// Whether the two agree: |z| < 4 (two-sided p ≈ 0.005 for a t statistic with 7 degrees of
    /// freedom), and the tile sum within 4 standard deviations of its expectation (a t₇² has
    /// mean 7/5 and variance 7.84). Catches a bias of a few standard errors of the image mean,
    /// or a larger one confined to a tile; not a bias smaller than the references' own noise.
    pub fn agrees(&self) -> bool {
        let n = self.tiles as f64;
        self.z.abs() < 4.0 && self.tile_chi2 <= 1.4 * n + 4.0 * (7.84 * n).sqrt()
    }
}

/// The image of part `part` in round `round` of `method`.
fn part_file(dir: &Path, method: &str, part: usize, round: usize) -> PathBuf {
    match round {
        0 => dir.join(format!("{method}_{part}.exr")),
        r => dir.join(format!("{method}_{part}_r{r}.exr")),
    }
}

/// The rounds of `method` complete in `dir` (their metadata and every part's image).
fn rounds_on_disk(dir: &Path, method: &str) -> Result<(usize, Value)> {
    let meta: Value = match std::fs::read(dir.join(format!("{method}.json"))) {
        Ok(bytes) => serde_json::from_slice(&bytes)?,
        Err(_) => json!({ "method": method, "rounds": [] }),
    };
    let listed = meta["rounds"].as_array().map_or(0, Vec::len);
    let complete = (0..listed)
        .take_while(|&r| (0..PARTS).all(|p| part_file(dir, method, p, r).is_file()))
        .count();
    Ok((complete, meta))
}

/// Renders the rounds of one estimator that `dir` lacks, up to `rounds`, and loads them, each
/// part merged over its rounds.
fn estimator(
    bin: &Path,
    dir: &Path,
    scene: &Path,
    settings: &RefSettings,
    index: usize,
    rounds: usize,
) -> Result<(Value, Estimator)> {
    let method = &settings.methods[index];
    let (on_disk, meta) = rounds_on_disk(dir, method)?;
    let mut round_metas: Vec<Value> = meta["rounds"].as_array().cloned().unwrap_or_default();
    round_metas.truncate(on_disk);
    let direct_samples = MANY_LIGHT_DIRECT_SAMPLES.to_string();
    let mut extra_args: Vec<&str> = Vec::new();
    if method != "pt" {
        extra_args.extend(["--direct-samples", &direct_samples]);
    }
    if let Some(only) = &settings.only {
        extra_args.extend(["--only", only]);
    }
    for round in on_disk..rounds {
        // A round after the first lasts as long as the earlier ones together: the time doubles.
        let seconds = (settings.seconds_of(round + 1) - settings.seconds_of(round)) / PARTS as f64;
        let mut parts = Vec::new();
        for part in 0..PARTS {
            // Seeds apart per estimator, part and round (64 apart per round: at most 2 × 8 parts).
            let seed = settings.seed_base + (index * PARTS + part) as u32 + 64 * round as u32;
            eprintln!(
                "bench: reference {} {method} round {} part {}/{PARTS}: {seconds:.0} s",
                scene.display(),
                round + 1,
                part + 1
            );
            let t = BeamlightRun {
                bin,
                scene,
                output: part_file(dir, method, part, round),
                method,
                backend: "cpu",
                budget: Budget::Seconds(seconds),
                seed,
                size: settings.size,
                components: true,
                extra_args: &extra_args,
            }
            .run()?;
            parts.push(json!({"spp": t.passes, "wall_seconds": t.wall, "render_seconds": t.render, "seed": seed}));
        }
        round_metas.push(Value::Array(parts));
        let meta = json!({ "method": method, "rounds": round_metas });
        std::fs::write(dir.join(format!("{method}.json")), serde_json::to_string_pretty(&meta)?)?;
    }
    let rounds = round_metas.len();
    let count = |r: usize, p: usize| round_metas[r][p]["spp"].as_u64().unwrap_or(1).max(1);
    // Each part is its rounds, and each half its parts, weighted by their sample counts, as
    // one longer render would be.
    let mut counts = Vec::new();
    let mut images = Vec::new();
    for part in 0..PARTS {
        let total: u64 = (0..rounds).map(|r| count(r, part)).sum();
        let mut renders = Vec::new();
        for r in 0..rounds {
            let render = metrics::read_beauty_and_layers(&part_file(dir, method, part, r))?;
            renders.push((render, count(r, part) as f64 / total as f64));
        }
        counts.push(total);
        images.push(weighted_sum(method, renders.iter().map(|(x, w)| (x, *w)))?);
    }
    let half = |range: std::ops::Range<usize>| {
        let total: u64 = counts[range.clone()].iter().sum();
        weighted_sum(method, range.map(|p| (&images[p], counts[p] as f64 / total as f64)))
    };
    let halves = [half(0..PARTS / 2)?, half(PARTS / 2..PARTS)?];
    let half_counts = [
        counts[..PARTS / 2].iter().sum::<u64>(),
        counts[PARTS / 2..].iter().sum::<u64>(),
    ];
    let est_rel_mse = halves_estimate(&halves[0].0, &halves[1].0, half_counts[0], half_counts[1])?.1;
    let est = Estimator {
        method: method.clone(),
        half_counts,
        seconds: round_metas
            .iter()
            .flat_map(|r| r.as_array().into_iter().flatten())
            .map(|p| p["wall_seconds"].as_f64().unwrap_or(0.0))
            .sum(),
        rounds,
        halves,
        parts: images.into_iter().map(|(_, l)| l).collect(),
        est_rel_mse,
    };
    Ok((json!({ "method": method, "rounds": round_metas }), est))
}

/// A beauty image with its component layers.
type Layered = (Image, Vec<(String, Image)>);

/// Σ wᵢ · renderᵢ over beauty and layers, which must be the same in every render.
fn weighted_sum<'a>(method: &str, renders: impl Iterator<Item = (&'a Layered, f64)>) -> Result<Layered> {
    let mut acc: Option<Layered> = None;
    for ((beauty, layers), w) in renders {
        let (sum, sums) = acc.get_or_insert_with(|| {
            let zero = Image::new(beauty.width, beauty.height);
            (
                zero.clone(),
                layers.iter().map(|(n, _)| (n.clone(), zero.clone())).collect(),
            )
        });
        *sum = metrics::blend(sum, 1.0, beauty, w)?;
        if sums.len() != layers.len() {
            bail!("{method}: reference renders have different layers");
        }
        for ((n, l), (m, x)) in sums.iter_mut().zip(layers) {
            if n != m {
                bail!("{method}: reference renders have different layers ({n} vs {m})");
            }
            *l = metrics::blend(l, 1.0, x, w)?;
        }
    }
    acc.context("no renders to merge")
}

impl Estimator {
    /// Samples per pixel (path tracers) or passes, summed over the parts.
    pub fn spp(&self) -> u64 {
        self.half_counts.iter().sum()
    }
}

/// relMSE(A, B) with B's denominators, and the merged reference's own relMSE from it: about a
/// quarter of the halves' when they have equal sample counts (in general wa²·eA + wb²·eB).
fn halves_estimate(a: &Image, b: &Image, na: u64, nb: u64) -> Result<(f64, f64)> {
    let (wa, wb) = (na as f64 / (na + nb) as f64, nb as f64 / (na + nb) as f64);
    let halves = metrics::rel_mse(a, b)?;
    Ok((halves, halves * (wa * wa + wb * wb) / 2.0))
}

/// The mean over pixels of (a − b)² summed over channels: an estimate of 2 × the per-pixel
/// variance of one half.
fn mean_sq_diff(a: &Image, b: &Image) -> f64 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (*x - *y).as_dvec3().length_squared())
        .sum::<f64>()
        / a.pixels.len().max(1) as f64
}

/// Means over a window of an image (RGB summed / 3), one per part, and their mean and standard
/// error (batch means).
fn batch_mean(parts: &[&Image], window: impl Fn(u32, u32) -> bool + Copy) -> (f64, f64) {
    let means: Vec<f64> = parts
        .iter()
        .map(|img| {
            let (mut sum, mut n) = (0.0f64, 0u64);
            for y in 0..img.height {
                for x in 0..img.width {
                    if window(x, y) {
                        sum += img.get(x, y).as_dvec3().element_sum() / 3.0;
                        n += 1;
                    }
                }
            }
            sum / n.max(1) as f64
        })
        .collect();
    let k = means.len() as f64;
    let mean = means.iter().sum::<f64>() / k;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
    (mean, (var / k).sqrt())
}

/// Compares two estimators on one layer (see [`CrossCheck`]).
fn cross_check(name: &str, a: &[&Image], b: &[&Image], weight0: f64) -> CrossCheck {
    let (ma, sa) = batch_mean(a, |_, _| true);
    let (mb, sb) = batch_mean(b, |_, _| true);
    let z = if sa + sb > 0.0 {
        (ma - mb) / (sa * sa + sb * sb).sqrt()
    } else if ma == mb {
        0.0
    } else {
        f64::INFINITY
    };
    let (w, h) = (a[0].width, a[0].height);
    let (mut chi2, mut tiles) = (0.0, 0);
    for ty in 0..4 {
        for tx in 0..4 {
            let inside = move |x: u32, y: u32| x * 4 / w == tx && y * 4 / h == ty;
            let (ta, tsa) = batch_mean(a, inside);
            let (tb, tsb) = batch_mean(b, inside);
            if ta == 0.0 && tb == 0.0 {
                continue;
            }
            let var = tsa * tsa + tsb * tsb;
            chi2 += if var > 0.0 {
                (ta - tb).powi(2) / var
            } else {
                f64::INFINITY
            };
            tiles += 1;
        }
    }
    CrossCheck {
        layer: name.to_string(),
        mean: [ma, mb],
        se: [sa, sb],
        z,
        tile_chi2: chi2,
        tiles,
        weight0,
    }
}

/// Makes the reference of `scene` (or reuses the cached one), in rounds until its own error
/// is within the goal or the time cap is reached.
pub fn make_or_reuse(bin: &Path, cache: &Path, scene: &Path, settings: &RefSettings) -> Result<Reference> {
    if settings.methods.is_empty() || settings.methods.len() > 2 {
        bail!("a reference takes one or two estimators, not {:?}", settings.methods);
    }
    let key = cache_key(scene, settings)?;
    let dir = entry_dir(cache, scene, &key);
    let reused = cached(cache, scene, settings)?.is_some();
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    // A cached entry resumes where its rounds ended (and renders nothing when they met the goal).
    let mut rounds: Vec<usize> = settings
        .methods
        .iter()
        .map(|m| Ok(rounds_on_disk(&dir, m)?.0.max(1)))
        .collect::<Result<_>>()?;
    loop {
        let mut metas = Vec::new();
        let mut estimators = Vec::new();
        for (i, &r) in rounds.iter().enumerate() {
            let (meta, e) = estimator(bin, &dir, scene, settings, i, r)?;
            metas.push(meta);
            estimators.push(e);
        }
        let merged = merge(estimators)?;
        let used: f64 = rounds.iter().map(|&r| settings.seconds_of(r)).sum();
        let next = (merged.est_rel_mse > settings.goal)
            .then(|| next_round(&merged))
            .flatten()
            .filter(|&i| used + settings.seconds_of(rounds[i]) <= settings.max_seconds);
        if let Some(i) = next {
            eprintln!(
                "bench: reference {}: own relMSE {:.2e} above the goal {:.2e}; {} renders a round more",
                scene.display(),
                merged.est_rel_mse,
                settings.goal,
                settings.methods[i]
            );
            rounds[i] += 1;
            continue;
        }
        let meta = json!({
            "key": key,
            "scene": scene.display().to_string(),
            "files": scene_files(scene)?.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "settings": settings.describe(),
            "estimators": metas,
        });
        std::fs::write(dir.join("meta.json"), serde_json::to_string_pretty(&meta)?)?;
        metrics::write_exr(&dir.join("reference.exr"), &merged.beauty)?;
        return Ok(Reference { dir, reused, ..merged });
    }
}

/// The estimator whose next round (doubling its time) lowers the merged reference's error
/// most per second, from each layer's variance between halves relative to the beauty (as
/// relMSE weighs it), combined by inverse variance as [`merge`] does. Layers are taken as
/// independent, which they are not within one estimator; this only orders the choices.
fn next_round(merged: &Reference) -> Option<usize> {
    let variances: Vec<Vec<f64>> = merged
        .estimators
        .iter()
        .map(|e| {
            e.halves[0]
                .1
                .iter()
                .zip(&e.halves[1].1)
                .map(|((_, a), (_, b))| relative_sq_diff(a, b, &merged.beauty))
                .collect()
        })
        .collect();
    let combined = |halved: Option<usize>| -> f64 {
        (0..variances[0].len())
            .map(|l| {
                let inv: f64 = variances
                    .iter()
                    .enumerate()
                    .map(|(i, v)| {
                        let v = if Some(i) == halved { v[l] / 2.0 } else { v[l] };
                        if v > 0.0 { 1.0 / v } else { f64::INFINITY }
                    })
                    .sum();
                1.0 / inv
            })
            .sum()
    };
    let now = combined(None);
    (0..variances.len())
        .map(|i| (i, (now - combined(Some(i))) / merged.estimators[i].seconds.max(1e-9)))
        .filter(|(_, gain)| *gain > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// The mean over pixels and channels of (a − b)² / (reference² + 0.01), relMSE's weights.
fn relative_sq_diff(a: &Image, b: &Image, reference: &Image) -> f64 {
    let mut sum = 0.0;
    for ((x, y), r) in a.pixels.iter().zip(&b.pixels).zip(&reference.pixels) {
        for c in 0..3 {
            let (e, r) = ((x[c] - y[c]) as f64, r[c] as f64);
            sum += e * e / (r * r + 1e-2);
        }
    }
    sum / (3 * a.pixels.len()).max(1) as f64
}

/// The estimators' renders merged into one reference (see the module doc).
fn merge(estimators: Vec<Estimator>) -> Result<Reference> {
    // The combined halves: one estimator's as they are; two estimators' per layer, weighted by
    // their inverse estimated variances, with the beauty the sum of the combined layers.
    let mut cross = Vec::new();
    let halves: [(Image, Vec<(String, Image)>); 2] = if estimators.len() == 1 {
        estimators[0].halves.clone()
    } else {
        let (e0, e1) = (&estimators[0], &estimators[1]);
        let names: Vec<String> = e0.halves[0].1.iter().map(|(n, _)| n.clone()).collect();
        if names != e1.halves[0].1.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>() {
            bail!(
                "the reference estimators {} and {} have different layers",
                e0.method,
                e1.method
            );
        }
        let mut out: [(Image, Vec<(String, Image)>); 2] = std::array::from_fn(|h| {
            let b = &e0.halves[h].0;
            (Image::new(b.width, b.height), Vec::new())
        });
        for (li, name) in names.iter().enumerate() {
            let var = |e: &Estimator| mean_sq_diff(&e.halves[0].1[li].1, &e.halves[1].1[li].1);
            let (v0, v1) = (var(e0), var(e1));
            let w0 = match (v0 > 0.0, v1 > 0.0) {
                (true, true) => (1.0 / v0) / (1.0 / v0 + 1.0 / v1),
                // A layer one estimator has noise-free (e.g. zero everywhere in both) or not at all.
                (false, _) => 1.0,
                (true, false) => 0.0,
            };
            let parts = |e: &'_ Estimator| -> Vec<Image> { e.parts.iter().map(|p| p[li].1.clone()).collect() };
            let (p0, p1) = (parts(e0), parts(e1));
            cross.push(cross_check(
                name,
                &p0.iter().collect::<Vec<_>>(),
                &p1.iter().collect::<Vec<_>>(),
                w0,
            ));
            for (h, half) in out.iter_mut().enumerate() {
                let layer = metrics::blend(&e0.halves[h].1[li].1, w0, &e1.halves[h].1[li].1, 1.0 - w0)?;
                half.0 = metrics::blend(&half.0, 1.0, &layer, 1.0)?;
                half.1.push((name.clone(), layer));
            }
        }
        // The sum of the layers is the beauty (each renderer writes it so; checked here, as the
        // combination relies on it).
        for e in &estimators {
            let b = &e.halves[0].0;
            let mut sum = Image::new(b.width, b.height);
            for (_, l) in &e.halves[0].1 {
                sum = metrics::blend(&sum, 1.0, l, 1.0)?;
            }
            let rel = metrics::rel_mse(&sum, b)?;
            if rel > 1e-8 {
                bail!(
                    "{}: the component layers do not sum to the beauty (relMSE {rel:.2e})",
                    e.method
                );
            }
        }
        out
    };
    // One estimator's halves are weighted by their sample counts; a combination's equally
    // (each estimator's halves hold about the same samples: their parts are equal-time).
    let [na, nb] = match &estimators[..] {
        [e] => e.half_counts,
        _ => [1, 1],
    };
    let (wa, wb) = (na as f64 / (na + nb) as f64, nb as f64 / (na + nb) as f64);
    let (halves_rel_mse, est_rel_mse) = halves_estimate(&halves[0].0, &halves[1].0, na, nb)?;
    let beauty = metrics::blend(&halves[0].0, wa, &halves[1].0, wb)?;
    let mut layers = Vec::new();
    let mut layer_est = Vec::new();
    for ((name, x), (_, y)) in halves[0].1.iter().zip(&halves[1].1) {
        layer_est.push((name.clone(), halves_estimate(x, y, na, nb)?.1));
        layers.push((name.clone(), metrics::blend(x, wa, y, wb)?));
    }
    Ok(Reference {
        dir: PathBuf::new(),
        beauty,
        layers,
        spp: estimators.iter().map(Estimator::spp).sum(),
        seconds: estimators.iter().map(|e| e.seconds).sum(),
        halves_rel_mse,
        est_rel_mse,
        layer_est_rel_mse: layer_est,
        reused: false,
        estimators,
        cross_check: cross,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> RefSettings {
        RefSettings {
            size: 32,
            seconds_per_half: 10.0,
            seed_base: 1,
            methods: vec!["pt".into()],
            renderer: "abc".into(),
            goal: 0.0,
            max_seconds: 40.0,
            only: None,
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
        // A reference of some components alone is another reference; a whole-image one's key
        // does not mention the restriction (so the keys of earlier runs still hold).
        let only = |c: &str| RefSettings {
            only: Some(c.into()),
            ..settings()
        };
        let k6 = cache_key(&scene, &only("Lmm")).unwrap();
        assert_ne!(k2, k6);
        assert_ne!(k6, cache_key(&scene, &only("Lmm,Lms")).unwrap());
        assert!(!settings().describe().contains("only"));
        // A cache entry written under the old key is not found for the new one.
        let cache = dir.path().join("cache");
        let entry = entry_dir(&cache, &scene, &k2);
        std::fs::create_dir_all(&entry).unwrap();
        for p in 0..PARTS {
            std::fs::write(entry.join(format!("pt_{p}.exr")), b"x").unwrap();
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

    /// `PARTS` noisy renders of a flat image of value `level` (uniform noise of ±0.2 per pixel).
    fn noisy_parts(level: f32, seed: u64) -> Vec<Image> {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.4
        };
        (0..PARTS)
            .map(|_| {
                let mut img = Image::new(16, 16);
                for p in img.pixels.iter_mut() {
                    *p = glam::Vec3::splat(level + next());
                }
                img
            })
            .collect()
    }

    /// The cross-check passes estimators of the same mean and flags a 5 % bias (and a bias
    /// confined to one tile in the tile sum). Per-part image means have a standard error of
    /// about 0.115 / 16 = 0.007, so 5 % of 1 is about 16 combined standard errors.
    #[test]
    fn cross_check_tells_agreeing_from_biased_estimators() {
        let a = noisy_parts(1.0, 1);
        let same = noisy_parts(1.0, 2);
        let biased = noisy_parts(1.05, 3);
        fn refs(v: &[Image]) -> Vec<&Image> {
            v.iter().collect()
        }
        let ok = cross_check("x", &refs(&a), &refs(&same), 0.5);
        assert!(ok.z.abs() < 4.0, "{ok:?}");
        assert_eq!(ok.tiles, 16);
        assert!(ok.agrees(), "{ok:?}");
        let bad = cross_check("x", &refs(&a), &refs(&biased), 0.5);
        assert!(bad.z.abs() > 8.0 && !bad.agrees(), "{bad:?}");
        // A bias in one corner only: 30 % in the top-left tile (16 pixels of 256).
        let mut corner = noisy_parts(1.0, 4);
        for img in corner.iter_mut() {
            for y in 0..4 {
                for x in 0..4 {
                    img.pixels[y * 16 + x] *= 1.3;
                }
            }
        }
        let local = cross_check("x", &refs(&a), &refs(&corner), 0.5);
        assert!(!local.agrees(), "{local:?}");
    }

    /// An estimator of one layer (the beauty equal to it) whose parts are 1 + uniform noise of
    /// ±`noise`, having taken `seconds`.
    fn fake_estimator(noise: f32, seconds: f64, seed: u64) -> Estimator {
        let parts: Vec<Image> = noisy_parts(1.0, seed)
            .into_iter()
            .map(|mut img| {
                for p in img.pixels.iter_mut() {
                    *p = glam::Vec3::ONE + (*p - glam::Vec3::ONE) * (noise / 0.2);
                }
                img
            })
            .collect();
        let layered: Vec<Layered> = parts
            .iter()
            .map(|p| (p.clone(), vec![("Lss".to_string(), p.clone())]))
            .collect();
        let half = |r: std::ops::Range<usize>| weighted_sum("x", layered[r].iter().map(|x| (x, 0.25))).unwrap();
        Estimator {
            method: format!("m{seed}"),
            half_counts: [4, 4],
            seconds,
            halves: [half(0..4), half(4..8)],
            parts: layered.into_iter().map(|(_, l)| l).collect(),
            est_rel_mse: 0.0,
            rounds: 1,
        }
    }

    /// The next round goes to the estimator that lowers the merged error most per second:
    /// the one carrying the combination's weight when both cost alike (as `vrl` does on
    /// `lamp_in_glass`, where `pt`'s own error is a thousand times larger), the other when
    /// that one's doubling would cost a thousand times more. Fails if the gain is not divided
    /// by the seconds or the halved variance is taken from the wrong estimator.
    #[test]
    fn the_next_round_goes_where_it_lowers_the_error_most_per_second() {
        let merged = merge(vec![fake_estimator(0.5, 100.0, 1), fake_estimator(0.05, 100.0, 2)]).unwrap();
        assert!(merged.cross_check[0].weight0 < 0.02, "{:?}", merged.cross_check);
        assert_eq!(next_round(&merged), Some(1));
        let merged = merge(vec![fake_estimator(0.5, 100.0, 1), fake_estimator(0.05, 1e5, 2)]).unwrap();
        assert_eq!(next_round(&merged), Some(0));
        // One estimator alone: it is the one to extend.
        let merged = merge(vec![fake_estimator(0.5, 100.0, 3)]).unwrap();
        assert_eq!(next_round(&merged), Some(0));
    }

    /// A round after the first lasts as long as all before it: the estimator's time doubles.
    #[test]
    fn rounds_double_an_estimators_time() {
        let s = settings();
        let times: Vec<f64> = (0..5).map(|r| s.seconds_of(r)).collect();
        assert_eq!(times, [0.0, 20.0, 40.0, 80.0, 160.0]);
    }
}
