//! The TOML sidecar: parsing (serde, unknown keys rejected) and positions for messages.
use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use std::collections::BTreeMap;
use std::fmt;
use toml::Spanned;

/// The whole sidecar file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Sidecar {
    /// The glTF file, relative to the sidecar.
    pub gltf: Spanned<String>,
    #[serde(default)]
    pub render: RenderToml,
    #[serde(default)]
    pub media: Vec<MediumToml>,
    #[serde(default)]
    pub materials: BTreeMap<Spanned<String>, MaterialToml>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RenderToml {
    pub width: Option<Spanned<u32>>,
    pub height: Option<Spanned<u32>>,
    pub camera: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MediumToml {
    pub name: Spanned<String>,
    pub region: Spanned<String>,
    pub sigma_s: Spanned<Rgb3>,
    pub sigma_a: Option<Spanned<Rgb3>>,
    pub g: Option<Spanned<f32>>,
    pub density: Option<Spanned<DensityToml>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DensityToml {
    /// A density file relative to the sidecar: `.vdb` (OpenVDB) or our raw `.bgrid`.
    pub grid: Option<Spanned<String>>,
    /// The grid's name in a `.vdb` file (default "density").
    pub name: Option<Spanned<String>>,
    /// A procedural density.
    pub perlin: Option<Spanned<PerlinToml>>,
    /// Resolution of the baked procedural grid: `n` or `[nx, ny, nz]`.
    pub resolution: Option<Spanned<Res3>>,
    /// `[[x0, y0, z0], [x1, y1, z1]]`, the world-space box the grid fills.
    pub bounds: Option<Spanned<[[f32; 3]; 2]>>,
}

/// `density = { perlin = { … } }`; every key optional (see `crate::noise`).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PerlinToml {
    pub scale: Option<Spanned<Num>>,
    pub octaves: Option<Spanned<i64>>,
    pub gain: Option<Spanned<Num>>,
    pub lacunarity: Option<Spanned<Num>>,
    pub height_falloff: Option<Spanned<Num>>,
    pub bias: Option<Spanned<Num>>,
    pub amplitude: Option<Spanned<Num>>,
    pub seed: Option<Spanned<i64>>,
}

/// A number written as a TOML integer or float.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Num(pub f64);

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Num;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Num, E> {
                Ok(Num(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Num, E> {
                Ok(Num(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Num, E> {
                Ok(Num(v as f64))
            }
        }
        d.deserialize_any(V)
    }
}

/// A resolution written as one integer (all axes) or `[nx, ny, nz]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Res3(pub [i64; 3]);

impl<'de> Deserialize<'de> for Res3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Res3;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an integer or [nx, ny, nz]")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Res3, E> {
                Ok(Res3([v; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Res3, E> {
                Ok(Res3([v.min(i64::MAX as u64) as i64; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Res3, A::Error> {
                let mut out = [0i64; 3];
                let mut n = 0usize;
                while let Some(v) = seq.next_element::<i64>()? {
                    if n < 3 {
                        out[n] = v;
                    }
                    n += 1;
                }
                if n != 3 {
                    return Err(de::Error::invalid_length(n, &"[nx, ny, nz]: exactly 3 integers"));
                }
                Ok(Res3(out))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialToml {
    pub kind: Option<Spanned<String>>,
    pub albedo: Option<Spanned<Rgb3>>,
    pub diffuse: Option<Spanned<Rgb3>>,
    pub specular: Option<Spanned<Rgb3>>,
    pub exponent: Option<Spanned<f32>>,
    pub reflectance: Option<Spanned<Rgb3>>,
    pub ior: Option<Spanned<f32>>,
    pub tint: Option<Spanned<Rgb3>>,
    pub emission: Option<Spanned<Rgb3>>,
    pub double_sided: Option<Spanned<bool>>,
}

/// An RGB triple written as `[r, g, b]` or as one number for all three channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Rgb3(pub [f32; 3]);

impl<'de> Deserialize<'de> for Rgb3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb3;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an RGB triple [r, g, b] or a single number")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rgb3, E> {
                Ok(Rgb3([v as f32; 3]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rgb3, E> {
                Ok(Rgb3([v as f32; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rgb3, E> {
                Ok(Rgb3([v as f32; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb3, A::Error> {
                let mut out = [0.0f32; 3];
                let mut n = 0usize;
                while let Some(v) = seq.next_element::<f64>()? {
                    if n < 3 {
                        out[n] = v as f32;
                    }
                    n += 1;
                }
                if n != 3 {
                    return Err(de::Error::invalid_length(n, &"an RGB triple of exactly 3 numbers"));
                }
                Ok(Rgb3(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// 1-based line and column of byte `offset` in `text`.
pub(super) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    let col = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1;
    (line, col)
}
