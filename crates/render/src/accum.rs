//! Accumulator files: a render's running sums (every film, beauty and components), the range
//! of passes they hold and a fingerprint of everything that decides a pass, so that a render
//! can be checkpointed and resumed (`--checkpoint`, `--resume`) or split into pass ranges on
//! several machines and merged (`--passes A..B`, `beamlight merge`). Sums are kept in f64, as
//! the films hold them: a resumed or merged render equals an uninterrupted one up to f64
//! rounding of the sums.
//!
//! Format: the 8 bytes `BLACCUM1`, a little-endian u32 header length, a JSON header, then for
//! each film (beauty first, then the components in `Component::ALL` order) its per-pixel sums
//! and sums of squares as little-endian f64 RGB triples.
use crate::{Film, output};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"BLACCUM1";

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
}

impl Accumulators {
    /// Passes held.
    pub fn passes(&self) -> u64 {
        self.film.samples
    }

    /// The pass after the last one held.
    pub fn end_pass(&self) -> u64 {
        self.first_pass + self.passes()
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), output::OutputError> {
        let films: Vec<&Film> = std::iter::once(&self.film).chain(&self.components).collect();
        let header = Header {
            fingerprint: self.fingerprint.clone(),
            first_pass: self.first_pass,
            passes: self.passes(),
            width: self.film.width,
            height: self.film.height,
            films: films.len() as u32,
            rejected: films.iter().map(|f| f.rejected).collect(),
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
        let body = &bytes[12 + len..];
        let film_bytes = pixels * 48;
        if body.len() != film_bytes * h.films as usize {
            return Err(err(
                path,
                format!(
                    "truncated or padded: {} bytes of sums, expected {}",
                    body.len(),
                    film_bytes * h.films as usize
                ),
            ));
        }
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
            films.push(
                Film::from_sums(
                    h.width,
                    h.height,
                    triples(sum),
                    triples(sum_sq),
                    h.passes,
                    h.rejected[k],
                )
                .expect("sizes checked above"),
            );
        }
        let film = films.remove(0);
        Ok(Accumulators {
            fingerprint: h.fingerprint,
            first_pass: h.first_pass,
            film,
            components: films,
        })
    }

    /// Combines renders of adjacent pass ranges of the same render into one. The parts may come
    /// in any order; they must have the same fingerprint and together cover one range without
    /// gaps or overlaps.
    pub fn merge(mut parts: Vec<(PathBuf, Accumulators)>) -> Result<Accumulators, String> {
        parts.sort_by_key(|(_, a)| a.first_pass);
        let mut iter = parts.into_iter();
        let (first_path, mut merged) = iter.next().ok_or("nothing to merge")?;
        for (path, part) in iter {
            if part.fingerprint != merged.fingerprint {
                return Err(format!(
                    "{} and {} come from different renders (scene or settings differ):\n  {}\n  {}",
                    first_path.display(),
                    path.display(),
                    merged.fingerprint,
                    part.fingerprint
                ));
            }
            if part.components.len() != merged.components.len() {
                return Err(format!("{}: a different set of component layers", path.display()));
            }
            if part.first_pass != merged.end_pass() {
                return Err(format!(
                    "{} holds passes {}..{}, but the parts before it end at pass {}: ranges must be adjacent, without gaps or overlaps",
                    path.display(),
                    part.first_pass,
                    part.end_pass(),
                    merged.end_pass()
                ));
            }
            merged.film.add_film(&part.film);
            for (a, b) in merged.components.iter_mut().zip(&part.components) {
                a.add_film(b);
            }
        }
        Ok(merged)
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

    #[test]
    fn merge_adds_adjacent_ranges_in_any_order() {
        let part = |first: u64, passes: u32| Accumulators {
            fingerprint: "f".into(),
            first_pass: first,
            film: film(2, 2, passes, first as f32),
            components: Vec::new(),
        };
        let m = Accumulators::merge(vec![("b".into(), part(3, 2)), ("a".into(), part(0, 3))]).unwrap();
        assert_eq!((m.first_pass, m.passes()), (0, 5));
        let e = Accumulators::merge(vec![("a".into(), part(0, 3)), ("b".into(), part(4, 2))]).unwrap_err();
        assert!(e.contains("adjacent"), "{e}");
    }
}
