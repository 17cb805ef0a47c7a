//! Accumulator files: a render's running sums (every film, beauty and components), the range
//! of passes they hold and a fingerprint of everything that decides a pass, so that a render
//! can be checkpointed and resumed (`--checkpoint`, `--resume`) or split into pass ranges on
//! several machines and merged (`--passes A..B`, `beamlight merge`). Sums are kept in f64, as
//! the films hold them: a resumed or merged render equals an uninterrupted one up to f64
//! rounding of the sums.
//!
//! Format: the 8 bytes `BLACCUM1`, a little-endian u32 header length, a JSON header, then for
//! each film (beauty first, then the components in `Component::ALL` order) its per-pixel sums
//! and sums of squares as little-endian f64 RGB triples. An `auto` render's files go on with
//! its two estimators' films (`pt`'s components, then `vbl`'s), described in the header's
//! `auto` entry; its beauty and component films hold the combination, which a merge computes
//! again from the merged estimators.
use crate::{Film, auto::AutoSums, auto::PassMeans, many_lights::Discards, output};
use std::{
    ops::Range,
    path::{Path, PathBuf},
};

const MAGIC: &[u8; 8] = b"BLACCUM1";
const N: usize = crate::components::Component::ALL.len();

/// FNV-1a, 64 bits: a stable content hash for fingerprints (accumulators, the benchmark's
/// reference cache), not a security hash. Std's hasher may change between Rust versions.
pub struct Fnv1a(pub u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    pub fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 ^ *b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }

    /// The floats' bit patterns, little-endian.
    pub fn write_f32s(&mut self, v: &[f32]) {
        for x in v {
            self.write(&x.to_bits().to_le_bytes());
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum AccumError {
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
}

fn err(path: &Path, message: impl ToString) -> AccumError {
    AccumError::File {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Header {
    fingerprint: String,
    first_pass: u64,
    passes: u64,
    width: u32,
    height: u32,
    films: u32,
    rejected: Vec<u64>,
    /// Estimates discarded per component (`Component::ALL` order) and light paths dropped
    /// ([`Discards`]); absent in files written before they were kept, which read as none.
    #[serde(default)]
    discarded: Vec<u64>,
    #[serde(default)]
    dropped_light_paths: u64,
    /// Partial passes (a time budget's shortened last pass) besides the whole `passes`; when
    /// there are any, the body ends with each pixel's count of them, little-endian u32s, which
    /// every film of the render shares.
    #[serde(default, skip_serializing_if = "is_zero")]
    partial_passes: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    auto: Option<AutoHeader>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// What an `auto` render keeps besides its films' sums ([`AutoSums`]).
#[derive(serde::Serialize, serde::Deserialize)]
struct AutoHeader {
    /// Samples and dropped samples of each estimator film, `pt`'s then `vbl`'s.
    samples: Vec<u64>,
    rejected: Vec<u64>,
    /// (passes, sum, sum of squares) of the passes' image means, per estimator film.
    means: Vec<[f64; 3]>,
    needed: Vec<bool>,
    vbl_only: Vec<bool>,
    pt_next: u64,
    vbl_next: u64,
}

/// A render's accumulated passes `first_pass .. first_pass + film.samples`.
#[derive(Clone, Debug)]
pub struct Accumulators {
    /// What must match for two accumulators to continue or combine each other: the scene's
    /// content, the method and every setting that changes a pass.
    pub fingerprint: String,
    pub first_pass: u64,
    pub film: Film,
    /// Per-component films (empty when the render kept no components).
    pub components: Vec<Film>,
    /// `--method auto`: the two estimators' sums, which `film` and `components` combine.
    pub auto: Option<AutoSums>,
    /// What the passes held had to leave out ([`Discards`]), so that a resumed or merged
    /// render reports what the whole one would.
    pub discarded: Discards,
}

impl Accumulators {
    /// Passes held, a shortened one included.
    pub fn passes(&self) -> u64 {
        self.film.passes()
    }

    /// The pass after the last one held.
    pub fn end_pass(&self) -> u64 {
        self.first_pass + self.passes()
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), output::OutputError> {
        let mut films: Vec<&Film> = std::iter::once(&self.film).chain(&self.components).collect();
        let regular = films.len() as u32;
        let auto = self.auto.as_ref().map(|a| {
            let estimators: Vec<&Film> = a.pt.iter().chain(&a.vbl).collect();
            films.extend(&estimators);
            AutoHeader {
                samples: estimators.iter().map(|f| f.samples).collect(),
                rejected: estimators.iter().map(|f| f.rejected).collect(),
                means: a
                    .pt_means
                    .iter()
                    .chain(&a.vbl_means)
                    .map(|m| [m.n, m.sum, m.sum_sq])
                    .collect(),
                needed: a.needed.to_vec(),
                vbl_only: a.vbl_only.to_vec(),
                pt_next: a.pt_next,
                vbl_next: a.vbl_next,
            }
        });
        let header = Header {
            fingerprint: self.fingerprint.clone(),
            first_pass: self.first_pass,
            passes: self.film.samples,
            partial_passes: self.film.partial_passes(),
            width: self.film.width,
            height: self.film.height,
            films: regular,
            rejected: films[..regular as usize].iter().map(|f| f.rejected).collect(),
            discarded: self.discarded.estimates.to_vec(),
            dropped_light_paths: self.discarded.light_paths,
            auto,
        };
        let json = serde_json::to_vec(&header).expect("the header serialises");
        let pixels = self.film.width as usize * self.film.height as usize;
        let mut bytes = Vec::with_capacity(12 + json.len() + films.len() * pixels * 48);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(json.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&json);
        for f in &films {
            let (sum, sum_sq) = f.sums();
            for v in sum.iter().chain(sum_sq).flatten() {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        if self.film.partial_passes() > 0 {
            for c in self.film.partial_counts() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        output::write_atomic(path, &bytes)
    }

    /// Reads a file written by [`Accumulators::write`], with a clear error for anything else.
    pub fn read(path: &Path) -> Result<Accumulators, AccumError> {
        let bytes = std::fs::read(path).map_err(|e| err(path, format!("cannot read: {e}")))?;
        if bytes.len() < 12 || &bytes[..8] != MAGIC {
            return Err(err(
                path,
                "not a beamlight accumulator file (written by --checkpoint or --passes A..B)",
            ));
        }
        let len = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes")) as usize;
        let json = bytes.get(12..12 + len).ok_or_else(|| err(path, "truncated header"))?;
        let h: Header = serde_json::from_slice(json).map_err(|e| err(path, format!("bad header: {e}")))?;
        let pixels = h.width as usize * h.height as usize;
        if h.films == 0 || h.rejected.len() != h.films as usize || pixels == 0 {
            return Err(err(path, "bad header: no films"));
        }
        let estimates = match h.discarded.len() {
            0 => [0; N],
            n if n == N => std::array::from_fn(|k| h.discarded[k]),
            n => return Err(err(path, format!("bad header: {n} discard counts for {N} components"))),
        };
        let discarded = Discards {
            estimates,
            light_paths: h.dropped_light_paths,
        };
        let body = &bytes[12 + len..];
        let film_bytes = pixels * 48;
        if let Some(a) = &h.auto
            && (a.samples.len() != 2 * N
                || a.rejected.len() != 2 * N
                || a.means.len() != 2 * N
                || a.needed.len() != N
                || a.vbl_only.len() != N)
        {
            return Err(err(path, "bad header: the auto render's entry is incomplete"));
        }
        let all_films = h.films as usize + h.auto.as_ref().map_or(0, |_| 2 * N);
        if h.partial_passes > 0 && h.auto.is_some() {
            return Err(err(path, "bad header: an auto render with partial passes"));
        }
        let count_bytes = if h.partial_passes > 0 { pixels * 4 } else { 0 };
        if body.len() != film_bytes * all_films + count_bytes {
            return Err(err(
                path,
                format!(
                    "truncated or padded: {} bytes of sums, expected {}",
                    body.len(),
                    film_bytes * all_films + count_bytes
                ),
            ));
        }
        let (body, counts) = body.split_at(film_bytes * all_films);
        let counts: Vec<u32> = counts
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .collect();
        let mut films = Vec::new();
        for (k, chunk) in body.chunks_exact(film_bytes).enumerate() {
            let values: Vec<f64> = chunk
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect();
            if values.iter().any(|v| !v.is_finite()) {
                return Err(err(path, format!("film {k} holds a non-finite sum")));
            }
            let triples = |v: &[f64]| v.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect::<Vec<_>>();
            let (sum, sum_sq) = values.split_at(pixels * 3);
            let (samples, rejected) = match k.checked_sub(h.films as usize) {
                None => (h.passes, h.rejected[k]),
                Some(j) => {
                    let a = h.auto.as_ref().expect("estimator films only with an auto entry");
                    (a.samples[j], a.rejected[j])
                }
            };
            let film = Film::from_sums(h.width, h.height, triples(sum), triples(sum_sq), samples, rejected)
                .expect("sizes checked above");
            let film = match k < h.films as usize {
                true => film.with_partial(h.partial_passes, counts.clone()).ok_or_else(|| {
                    err(
                        path,
                        format!("a pixel counts more than the {} partial passes", h.partial_passes),
                    )
                })?,
                false => film,
            };
            films.push(film);
        }
        let auto = h.auto.map(|a| {
            let vbl = films.split_off(films.len() - N);
            let pt = films.split_off(films.len() - N);
            let means = |i: usize| {
                let [n, sum, sum_sq] = a.means[i];
                PassMeans { n, sum, sum_sq }
            };
            AutoSums {
                pt,
                vbl,
                pt_means: std::array::from_fn(means),
                vbl_means: std::array::from_fn(|k| means(N + k)),
                needed: std::array::from_fn(|k| a.needed[k]),
                vbl_only: std::array::from_fn(|k| a.vbl_only[k]),
                pt_next: a.pt_next,
                vbl_next: a.vbl_next,
            }
        });
        let film = films.remove(0);
        Ok(Accumulators {
            fingerprint: h.fingerprint,
            first_pass: h.first_pass,
            film,
            components: films,
            auto,
            discarded,
        })
    }

    /// Combines renders of adjacent pass ranges of the same render into one. The parts may come
    /// in any order; they must have the same fingerprint and together cover one range without
    /// gaps or overlaps: `expected`, when given, or else the span from the first part's first pass
    /// to the last part's end. Returns the merged accumulators and which ranges were present; the
    /// error for an incomplete or overlapping set names the missing ranges and lists every part's.
    pub fn merge(
        mut parts: Vec<(PathBuf, Accumulators)>,
        expected: Option<Range<u64>>,
    ) -> Result<(Accumulators, Coverage), String> {
        parts.sort_by_key(|(_, a)| (a.first_pass, a.end_pass()));
        let Some((first_path, first)) = parts.first() else {
            return Err("nothing to merge".into());
        };
        for (path, part) in &parts[1..] {
            if part.fingerprint != first.fingerprint {
                return Err(format!(
                    "{} and {} come from different renders (scene or settings differ):\n  {}\n  {}",
                    first_path.display(),
                    path.display(),
                    first.fingerprint,
                    part.fingerprint
                ));
            }
            if part.components.len() != first.components.len() {
                return Err(format!("{}: a different set of component layers", path.display()));
            }
        }
        let ranges: Vec<(PathBuf, Range<u64>)> = parts
            .iter()
            .map(|(p, a)| (p.clone(), a.first_pass..a.end_pass()))
            .collect();
        let coverage = Coverage::of(&ranges, expected);
        if let Some(problem) = coverage.problem() {
            return Err(format!("{problem}; the parts hold:\n{coverage}"));
        }
        let mut iter = parts.into_iter();
        let (_, mut merged) = iter.next().expect("one part at least");
        for (_, part) in iter {
            merged.film.add_film(&part.film);
            merged.discarded.add(&part.discarded);
            for (a, b) in merged.components.iter_mut().zip(&part.components) {
                a.add_film(b);
            }
            match (&mut merged.auto, &part.auto) {
                (Some(a), Some(b)) => a.add(b),
                (None, None) => {}
                _ => return Err("an auto render's parts cannot merge with another method's".into()),
            }
        }
        // An `auto` render's image is not a sum: combine the merged estimators again.
        if let Some(sums) = &merged.auto {
            let (film, components, _) = sums.combined(merged.passes());
            let rejected = sums.pt.iter().chain(&sums.vbl).map(|f| f.rejected).sum();
            merged.film = film;
            merged.film.rejected = rejected;
            if !merged.components.is_empty() {
                merged.components = components;
            }
        }
        Ok((merged, coverage))
    }
}

/// Which passes a set of parts holds, against the range they should cover together.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Coverage {
    /// The range the parts should cover.
    pub expected: Range<u64>,
    /// Each part's file and passes, in pass order.
    pub present: Vec<(PathBuf, Range<u64>)>,
    /// Ranges of `expected` that no part holds, in order.
    pub missing: Vec<Range<u64>>,
}

impl Coverage {
    /// The coverage of `expected` (default: from the first part's start to the last part's end)
    /// by the parts' ranges.
    pub fn of(parts: &[(PathBuf, Range<u64>)], expected: Option<Range<u64>>) -> Coverage {
        let mut present = parts.to_vec();
        present.sort_by_key(|(_, r)| (r.start, r.end));
        let expected = expected.unwrap_or_else(|| {
            let start = present.iter().map(|(_, r)| r.start).min().unwrap_or(0);
            let end = present.iter().map(|(_, r)| r.end).max().unwrap_or(0);
            start..end
        });
        let mut missing = Vec::new();
        let mut covered = expected.start;
        for (_, r) in &present {
            if r.start > covered && covered < expected.end {
                missing.push(covered..r.start.min(expected.end));
            }
            covered = covered.max(r.end);
        }
        if covered < expected.end {
            missing.push(covered..expected.end);
        }
        Coverage {
            expected,
            present,
            missing,
        }
    }

    /// Why the parts do not merge into exactly `expected`: missing ranges, overlapping parts, or
    /// parts outside it. `None` when they tile it.
    pub fn problem(&self) -> Option<String> {
        let ranges = |rs: &[Range<u64>]| rs.iter().map(|r| format!("{}..{}", r.start, r.end)).collect::<Vec<_>>();
        let (e, mut problems) = (&self.expected, Vec::new());
        if !self.missing.is_empty() {
            let m = ranges(&self.missing).join(", ");
            let how = match self.missing.as_slice() {
                [r] => format!("render them with `--passes {}..{}`", r.start, r.end),
                _ => "render each range with `--passes A..B`".into(),
            };
            problems.push(format!(
                "passes {m} are missing: {how} (same scene and settings) and merge again"
            ));
        }
        // The part reaching furthest so far: a later part starting before its end overlaps it.
        let mut furthest: Option<&(PathBuf, Range<u64>)> = None;
        for part in &self.present {
            if let Some(f) = furthest.filter(|f| part.1.start < f.1.end) {
                problems.push(format!(
                    "{} ({}..{}) and {} ({}..{}) overlap: ranges must be adjacent, without gaps or overlaps",
                    f.0.display(),
                    f.1.start,
                    f.1.end,
                    part.0.display(),
                    part.1.start,
                    part.1.end
                ));
            }
            if furthest.is_none_or(|f| part.1.end > f.1.end) {
                furthest = Some(part);
            }
        }
        for (p, r) in &self.present {
            if r.start < e.start || r.end > e.end {
                problems.push(format!(
                    "{} holds passes {}..{}, outside the merged range {}..{}",
                    p.display(),
                    r.start,
                    r.end,
                    e.start,
                    e.end
                ));
            }
        }
        (!problems.is_empty()).then(|| problems.join("\n"))
    }
}

/// One line per range of the expected passes, in pass order: `  0..2  present  a.accum` or
/// `  2..4  MISSING`, then a total.
impl std::fmt::Display for Coverage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut rows: Vec<(Range<u64>, Option<&Path>)> = self
            .present
            .iter()
            .map(|(p, r)| (r.clone(), Some(p.as_path())))
            .collect();
        rows.extend(self.missing.iter().map(|r| (r.clone(), None)));
        rows.sort_by_key(|(r, p)| (r.start, p.is_none(), r.end));
        let width = rows
            .iter()
            .map(|(r, _)| format!("{}..{}", r.start, r.end).len())
            .max()
            .unwrap_or(0);
        for (r, p) in rows {
            let range = format!("{}..{}", r.start, r.end);
            match p {
                Some(p) => writeln!(f, "  {range:<width$}  present  {}", p.display())?,
                None => writeln!(f, "  {range:<width$}  MISSING")?,
            }
        }
        let (e, missing) = (
            &self.expected,
            self.missing.iter().map(|r| r.end - r.start).sum::<u64>(),
        );
        let parts = self.present.len();
        if missing == 0 {
            write!(f, "  passes {}..{}: complete, {parts} parts", e.start, e.end)
        } else {
            write!(
                f,
                "  passes {}..{}: {missing} of {} missing ({} {}), {parts} parts present",
                e.start,
                e.end,
                e.end - e.start,
                self.missing.len(),
                if self.missing.len() == 1 { "range" } else { "ranges" }
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use beamlight_scene::Rgb;

    fn film(w: u32, h: u32, passes: u32, value: f32) -> Film {
        let mut f = Film::new(w, h);
        for k in 0..passes {
            let pass: Vec<Rgb> = (0..w * h).map(|i| Rgb::new(value, i as f32, k as f32)).collect();
            f.add_pass(&pass);
        }
        f
    }

    #[test]
    fn round_trip_and_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.accum");
        let acc = Accumulators {
            fingerprint: "scene 1; vbl".into(),
            first_pass: 7,
            film: film(3, 2, 4, 0.5),
            components: vec![film(3, 2, 4, 0.25), film(3, 2, 4, 0.0)],
            auto: None,
            discarded: Discards {
                estimates: [0, 3, 0, 1, 0, 0, 7],
                light_paths: 2,
            },
        };
        acc.write(&path).unwrap();
        let back = Accumulators::read(&path).unwrap();
        assert_eq!(
            (back.first_pass, back.passes(), back.fingerprint.as_str()),
            (7, 4, "scene 1; vbl")
        );
        assert_eq!(back.film.sums(), acc.film.sums());
        assert_eq!(back.components.len(), 2);
        assert_eq!(back.components[0].sums(), acc.components[0].sums());
        assert_eq!(back.discarded, acc.discarded);
        // Truncated, or not an accumulator file at all: an error naming the file.
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
        let e = Accumulators::read(&path).unwrap_err().to_string();
        assert!(e.contains("a.accum") && e.contains("truncated"), "{e}");
        std::fs::write(&path, b"not this").unwrap();
        assert!(
            Accumulators::read(&path)
                .unwrap_err()
                .to_string()
                .contains("not a beamlight accumulator file")
        );
    }

    /// A render that ended with a shortened pass: its per-pixel counts survive the file and a
    /// merge, its pass range counts the shortened pass, and a file whose counts exceed its
    /// partial passes is refused by name. Catches counts dropped on the way (the pixels'
    /// means would then divide by the whole passes alone).
    #[test]
    fn a_shortened_pass_round_trips_and_merges() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.accum");
        let shortened = |first: u64, passes: u32| {
            let mut f = film(3, 2, passes, 1.0);
            f.add_partial_pass(&[Rgb::splat(4.0); 6], |i| i % 2 == 0);
            Accumulators {
                fingerprint: "f".into(),
                first_pass: first,
                components: vec![f.clone()],
                film: f,
                auto: None,
                discarded: Discards::default(),
            }
        };
        let acc = shortened(0, 2);
        assert_eq!((acc.passes(), acc.end_pass()), (3, 3));
        acc.write(&path).unwrap();
        let back = Accumulators::read(&path).unwrap();
        assert_eq!(back.passes(), 3);
        assert_eq!(back.film.partial_counts(), &[1, 0, 1, 0, 1, 0]);
        assert_eq!(back.components[0].partial_counts(), &[1, 0, 1, 0, 1, 0]);
        assert_eq!(back.film.image(), acc.film.image());
        let (m, _) = Accumulators::merge(vec![("a".into(), back), ("b".into(), shortened(3, 1))], None).unwrap();
        assert_eq!((m.end_pass(), m.film.samples, m.film.partial_passes()), (5, 3, 2));
        assert_eq!(m.film.partial_counts(), &[2, 0, 2, 0, 2, 0]);
        // Pixel 1's red: three samples of 1; pixel 0's: those and two of 4.
        assert_eq!(
            (m.film.image().pixels[0][0], m.film.image().pixels[1][0]),
            (11.0 / 5.0, 1.0)
        );
        // A count above the partial passes: corrupt.
        let mut bytes = std::fs::read(&path).unwrap();
        let n = bytes.len();
        bytes[n - 4..].copy_from_slice(&7u32.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let e = Accumulators::read(&path).unwrap_err().to_string();
        assert!(e.contains("p.accum") && e.contains("partial passes"), "{e}");
    }

    #[test]
    fn merge_adds_adjacent_ranges_in_any_order() {
        let part = |first: u64, passes: u32| Accumulators {
            fingerprint: "f".into(),
            first_pass: first,
            film: film(2, 2, passes, first as f32),
            components: Vec::new(),
            auto: None,
            discarded: Discards {
                estimates: [first, 0, 0, 0, 0, 0, 1],
                light_paths: 1,
            },
        };
        let (m, cov) = Accumulators::merge(vec![("b".into(), part(3, 2)), ("a".into(), part(0, 3))], None).unwrap();
        assert_eq!((m.first_pass, m.passes()), (0, 5));
        let want = Discards {
            estimates: [3, 0, 0, 0, 0, 0, 2],
            light_paths: 2,
        };
        assert_eq!(m.discarded, want, "the parts' discard counts add up");
        assert_eq!(cov.missing, Vec::<Range<u64>>::new());
        assert_eq!(
            cov.to_string(),
            "  0..3  present  a\n  3..5  present  b\n  passes 0..5: complete, 2 parts"
        );
        let e = Accumulators::merge(vec![("a".into(), part(0, 3)), ("b".into(), part(2, 2))], None).unwrap_err();
        assert!(e.contains("adjacent"), "{e}");
        let e = Accumulators::merge(vec![("a".into(), part(0, 3)), ("b".into(), part(4, 2))], None).unwrap_err();
        assert!(
            e.starts_with("passes 3..4 are missing: render them with `--passes 3..4`"),
            "{e}"
        );
        assert!(e.contains("  3..4  MISSING\n"), "{e}");
        // Against an expected range, missing ends count too; parts outside it are refused.
        let e = Accumulators::merge(vec![("a".into(), part(2, 3))], Some(0..8)).unwrap_err();
        assert!(e.starts_with("passes 0..2, 5..8 are missing"), "{e}");
        let e = Accumulators::merge(vec![("a".into(), part(0, 3))], Some(0..2)).unwrap_err();
        assert!(e.contains("outside the merged range 0..2"), "{e}");
        assert!(Accumulators::merge(vec![("a".into(), part(0, 3))], Some(0..3)).is_ok());
    }

    #[test]
    fn coverage_lists_present_and_missing_ranges_in_order() {
        let parts: Vec<(PathBuf, Range<u64>)> = vec![("p3".into(), 6..8), ("p0".into(), 0..2), ("p1".into(), 2..4)];
        let cov = Coverage::of(&parts, Some(0..10));
        assert_eq!(cov.missing, vec![4..6, 8..10]);
        assert_eq!(
            cov.to_string(),
            "  0..2   present  p0\n  2..4   present  p1\n  4..6   MISSING\n  6..8   present  p3\n  8..10  MISSING\n  passes 0..10: 4 of 10 missing (2 ranges), 3 parts present"
        );
    }
}
