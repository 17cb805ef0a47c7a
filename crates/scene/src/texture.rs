//! Colour textures (the glTF `baseColorTexture`): linear-RGB `f32` texels, bilinear lookup,
//! glTF/OpenGL wrap modes.
//!
//! Conventions:
//! * **uv origin**: glTF's. `(0, 0)` is the top-left corner of the image, i.e. the start of the
//!   first texel in memory (the first row of a PNG/JPEG); `u` grows to the right along a row
//!   and `v` downwards across rows. No flip is applied anywhere. Texel `(x, y)` covers
//!   `[x/w, (x+1)/w] × [y/h, (y+1)/h]` and its centre is at `((x+½)/w, (y+½)/h)`.
//! * **Filtering**: always bilinear between the four nearest texel centres (the glTF sampler's
//!   `magFilter`/`minFilter` are ignored; there is no mip-mapping). The result is a convex
//!   combination of texels, so it never exceeds the brightest texel.
//! * **Wrap modes** (per axis, `wrapS` for u and `wrapT` for v) are applied to texel indices,
//!   which is what OpenGL does: `REPEAT` (the glTF default), `CLAMP_TO_EDGE`, `MIRRORED_REPEAT`.
//! * **Colour**: texels hold linear RGB in [0, 1]. Images are sRGB-encoded (as glTF specifies
//!   for base colour) and are decoded with the exact sRGB EOTF, [`srgb_to_linear`]; alpha is
//!   ignored.
use crate::Rgb;
use glam::Vec2;
use std::sync::Arc;

/// How texture coordinates outside [0, 1] map onto the image (glTF sampler `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    /// The image tiles the plane (glTF `REPEAT`, 10497, the default).
    #[default]
    Repeat,
    /// Coordinates are clamped so the edge texels extend outwards (glTF `CLAMP_TO_EDGE`, 33071).
    ClampToEdge,
    /// The image tiles the plane, every other copy mirrored (glTF `MIRRORED_REPEAT`, 33648).
    MirroredRepeat,
}

impl Wrap {
    /// The glTF/OpenGL enum value.
    pub fn gl_enum(self) -> u32 {
        match self {
            Wrap::Repeat => 10497,
            Wrap::ClampToEdge => 33071,
            Wrap::MirroredRepeat => 33648,
        }
    }

    /// Brings a coordinate into a bounded range without changing what it maps to (keeps
    /// precision and avoids overflow for huge or non-finite coordinates).
    #[inline]
    fn reduce(self, u: f32) -> f32 {
        if !u.is_finite() {
            return 0.0;
        }
        match self {
            Wrap::Repeat => u - u.floor(),
            Wrap::MirroredRepeat => u.rem_euclid(2.0),
            Wrap::ClampToEdge => u.clamp(-1.0, 2.0),
        }
    }

    /// Maps a texel index (any integer) onto `0..n`.
    #[inline]
    fn index(self, i: i64, n: i64) -> usize {
        (match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        }) as usize
    }
}

/// The exact sRGB electro-optical transfer function (IEC 61966-2-1): encoded value in [0, 1]
/// → linear value in [0, 1].
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A linear-RGB image with wrap modes; see the [module documentation](self) for the conventions.
/// Texels are shared (cheap to clone).
#[derive(Clone, PartialEq)]
pub struct Texture {
    name: String,
    width: u32,
    height: u32,
    /// Row-major, first row = top of the image (v = 0).
    texels: Arc<[Rgb]>,
    wrap_s: Wrap,
    wrap_t: Wrap,
    /// Per-channel maximum over all texels.
    max_texel: Rgb,
}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Texture")
            .field("name", &self.name)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("wrap_s", &self.wrap_s)
            .field("wrap_t", &self.wrap_t)
            .field("max_texel", &self.max_texel)
            .finish_non_exhaustive()
    }
}

impl Texture {
    /// A texture of `width × height` linear-RGB texels (row-major, first row at v = 0).
    /// Every texel must be finite and in [0, 1] (it is a reflectance); errors say what is wrong.
    pub fn new(
        name: impl Into<String>,
        width: u32,
        height: u32,
        texels: impl Into<Arc<[Rgb]>>,
        wrap_s: Wrap,
        wrap_t: Wrap,
    ) -> Result<Self, String> {
        let texels = texels.into();
        if width == 0 || height == 0 {
            return Err(format!("texture size {width}x{height} is empty"));
        }
        if texels.len() as u64 != width as u64 * height as u64 {
            return Err(format!(
                "texture size {width}x{height} needs {} texels, got {}",
                width as u64 * height as u64,
                texels.len()
            ));
        }
        let mut max_texel = Rgb::ZERO;
        for (i, t) in texels.iter().enumerate() {
            if !(t.is_finite() && t.min_element() >= 0.0 && t.max_element() <= 1.0) {
                return Err(format!(
                    "texel ({}, {}) = {t} is not in [0, 1]",
                    i % width as usize,
                    i / width as usize
                ));
            }
            max_texel = max_texel.max(*t);
        }
        Ok(Self {
            name: name.into(),
            width,
            height,
            texels,
            wrap_s,
            wrap_t,
            max_texel,
        })
    }

    /// What the texture was made from (for messages), e.g. `image 2 'wood.png'`.
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn wrap_s(&self) -> Wrap {
        self.wrap_s
    }

    pub fn wrap_t(&self) -> Wrap {
        self.wrap_t
    }

    /// Per-channel maximum over all texels: the most any lookup can return.
    pub fn max_texel(&self) -> Rgb {
        self.max_texel
    }

    /// Texel `(x, y)` (x along a row, y = 0 the top row). Panics when out of range.
    pub fn texel(&self, x: u32, y: u32) -> Rgb {
        assert!(x < self.width && y < self.height, "texel ({x}, {y}) out of range");
        self.texels[y as usize * self.width as usize + x as usize]
    }

    /// Bilinear lookup at `uv` (glTF convention: (0, 0) is the top-left corner of the image),
    /// with the texture's wrap modes. Finite and within [0, max_texel] for every input
    /// (non-finite coordinates are treated as 0).
    pub fn sample(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = self.wrap_s.reduce(uv.x) * self.width as f32 - 0.5;
        let y = self.wrap_t.reduce(uv.y) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let (xa, xb) = (self.wrap_s.index(xi, w), self.wrap_s.index(xi + 1, w));
        let (ya, yb) = (self.wrap_t.index(yi, h), self.wrap_t.index(yi + 1, h));
        let row = self.width as usize;
        let t = |x: usize, y: usize| self.texels[y * row + x];
        let top = t(xa, ya) * (1.0 - fx) + t(xb, ya) * fx;
        let bottom = t(xa, yb) * (1.0 - fx) + t(xb, yb) * fx;
        // Rounding could push a convex combination a hair past its largest term.
        (top * (1.0 - fy) + bottom * fy).clamp(Rgb::ZERO, self.max_texel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32, wrap_s: Wrap, wrap_t: Wrap) -> Texture {
        let texels: Vec<Rgb> = (0..h)
            .flat_map(|y| (0..w).map(move |x| Rgb::new(x as f32 / w as f32, y as f32 / h as f32, 0.5)))
            .collect();
        Texture::new("ramp", w, h, texels, wrap_s, wrap_t).unwrap()
    }

    #[test]
    fn texel_centres_are_exact() {
        let t = ramp(4, 3, Wrap::Repeat, Wrap::Repeat);
        for y in 0..3 {
            for x in 0..4 {
                let uv = Vec2::new((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 3.0);
                assert_eq!(t.sample(uv), t.texel(x, y));
            }
        }
    }

    #[test]
    fn bilinear_between_centres() {
        let t = ramp(4, 4, Wrap::ClampToEdge, Wrap::ClampToEdge);
        // Halfway between texel centres 1 and 2 along u: the mean of the two.
        let v = t.sample(Vec2::new(0.5, 0.375));
        assert!((v.x - 0.375).abs() < 1e-6 && (v.y - 0.25).abs() < 1e-6, "{v}");
    }

    #[test]
    fn wrap_modes() {
        let (w, h) = (4i64, 2i64);
        for i in -9..9 {
            assert_eq!(Wrap::Repeat.index(i, w), i.rem_euclid(4) as usize);
            assert_eq!(Wrap::ClampToEdge.index(i, w), i.clamp(0, 3) as usize);
        }
        let mirrored: Vec<usize> = (-4..6).map(|i| Wrap::MirroredRepeat.index(i, h)).collect();
        assert_eq!(mirrored, [0, 1, 1, 0, 0, 1, 1, 0, 0, 1]);
        let t = ramp(4, 4, Wrap::Repeat, Wrap::MirroredRepeat);
        let c = Vec2::new(0.125, 0.375);
        assert_eq!(t.sample(c + Vec2::new(3.0, 0.0)), t.sample(c));
        assert_eq!(t.sample(c + Vec2::new(-7.0, 0.0)), t.sample(c));
        // Mirrored in v: v and 2 − v (and −v) give the same value.
        assert_eq!(t.sample(Vec2::new(0.125, 2.0 - 0.375)), t.sample(c));
        assert_eq!(t.sample(Vec2::new(0.125, -0.375)), t.sample(c));
        let t = ramp(4, 4, Wrap::ClampToEdge, Wrap::ClampToEdge);
        assert_eq!(t.sample(Vec2::new(-5.0, 7.0)), t.texel(0, 3));
    }

    #[test]
    fn never_nan_and_bounded() {
        let t = ramp(3, 5, Wrap::MirroredRepeat, Wrap::Repeat);
        for uv in [
            Vec2::new(f32::NAN, 0.2),
            Vec2::new(f32::INFINITY, f32::NEG_INFINITY),
            Vec2::new(3.0e38, -3.0e38),
            Vec2::new(-1e-9, 1.0),
            Vec2::new(12345.678, -0.0),
        ] {
            let v = t.sample(uv);
            assert!(
                v.is_finite() && v.min_element() >= 0.0 && v.cmple(t.max_texel()).all(),
                "{uv} -> {v}"
            );
        }
    }

    #[test]
    fn srgb_eotf() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert_eq!(srgb_to_linear(1.0), 1.0);
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-15);
        assert!((srgb_to_linear(0.5) - 0.214_041_140_482_232_55).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_texels() {
        assert!(Texture::new("t", 1, 1, vec![Rgb::new(1.5, 0.0, 0.0)], Wrap::Repeat, Wrap::Repeat).is_err());
        assert!(Texture::new("t", 2, 1, vec![Rgb::ZERO], Wrap::Repeat, Wrap::Repeat).is_err());
        assert!(Texture::new("t", 0, 0, Vec::<Rgb>::new(), Wrap::Repeat, Wrap::Repeat).is_err());
    }
}
