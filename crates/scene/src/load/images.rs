//! Base-colour textures: glTF `textures`/`images`/`samplers` → decoded, linear-RGB
//! [`Texture`]s. Each image is read and decoded once, on first use; materials that use the same
//! image with the same wrap modes share one [`Texture`].
use super::Src;
use super::gltf_read::{self, GltfDoc};
use crate::texture::{Texture, Wrap, srgb_to_linear};
use crate::{Rgb, SceneError};
use gltf::json::{texture::WrappingMode, validation::Checked};
use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::Arc;

/// Largest image side we decode.
const MAX_SIDE: u32 = 16384;
/// Most texels in one image (an 8192² image; 768 MiB as linear f32 RGB).
const MAX_TEXELS: u64 = 1 << 26;

/// A decoded image: linear texels, row-major, first row on top.
struct Decoded {
    label: String,
    width: u32,
    height: u32,
    texels: Arc<[Rgb]>,
}

pub(super) struct TextureLoader<'a> {
    src: &'a Src,
    doc: &'a GltfDoc,
    /// By glTF image index: `None` not read yet, `Some(None)` unsupported format (warned once).
    images: Vec<Option<Option<Decoded>>>,
    /// (image, wrapS, wrapT) → index into `textures`.
    shared: HashMap<(usize, Wrap, Wrap), u32>,
    pub textures: Vec<Texture>,
}

impl<'a> TextureLoader<'a> {
    pub fn new(src: &'a Src, doc: &'a GltfDoc) -> Self {
        Self {
            src,
            doc,
            images: (0..doc.root.images.len()).map(|_| None).collect(),
            shared: HashMap::new(),
            textures: Vec::new(),
        }
    }

    /// The scene texture for glTF texture `index`, as used by `who` (e.g. `material 'Floor'
    /// baseColorTexture`), reading and decoding its image on first use. `Ok(None)` when the
    /// image's format is not supported (a warning is recorded once per image): the caller falls
    /// back to the constant factor.
    pub fn load(&mut self, index: usize, who: &str, warnings: &mut Vec<String>) -> Result<Option<u32>, SceneError> {
        let root = &self.doc.root;
        let src = self.src;
        let tex = root
            .textures
            .get(index)
            .ok_or_else(|| src.err(format!("{who}: texture {index} does not exist")))?;
        let (wrap_s, wrap_t) = match tex.sampler {
            None => (Wrap::Repeat, Wrap::Repeat),
            Some(s) => {
                let sampler = root
                    .samplers
                    .get(s.value())
                    .ok_or_else(|| src.err(format!("{who}: texture {index}: sampler {} does not exist", s.value())))?;
                let wrap = |w: &Checked<WrappingMode>, key: &str| match w {
                    Checked::Valid(WrappingMode::Repeat) => Ok(Wrap::Repeat),
                    Checked::Valid(WrappingMode::ClampToEdge) => Ok(Wrap::ClampToEdge),
                    Checked::Valid(WrappingMode::MirroredRepeat) => Ok(Wrap::MirroredRepeat),
                    Checked::Invalid => {
                        Err(src.err(format!("{who}: texture {index}: sampler {}: invalid {key}", s.value())))
                    }
                };
                (wrap(&sampler.wrap_s, "wrapS")?, wrap(&sampler.wrap_t, "wrapT")?)
            }
        };
        let image = tex.source.value();
        if image >= root.images.len() {
            return Err(src.err(format!("{who}: texture {index}: image {image} does not exist")));
        }
        if let Some(&t) = self.shared.get(&(image, wrap_s, wrap_t)) {
            return Ok(Some(t));
        }
        if self.images[image].is_none() {
            self.images[image] = Some(self.read_image(image, who, warnings)?);
        }
        let Some(Some(d)) = &self.images[image] else {
            return Ok(None);
        };
        let texture = Texture::new(d.label.clone(), d.width, d.height, d.texels.clone(), wrap_s, wrap_t)
            .map_err(|e| src.err(format!("{who}: {}: {e}", d.label)))?;
        self.textures.push(texture);
        let t = (self.textures.len() - 1) as u32;
        self.shared.insert((image, wrap_s, wrap_t), t);
        Ok(Some(t))
    }

    /// Reads and decodes image `i`; `None` (with a warning) when its format is unsupported.
    fn read_image(&self, i: usize, who: &str, warnings: &mut Vec<String>) -> Result<Option<Decoded>, SceneError> {
        let src = self.src;
        let img = &self.doc.root.images[i];
        let shown = img
            .name
            .as_deref()
            .or(img.uri.as_deref().filter(|u| !u.starts_with("data:")));
        let label = match shown {
            Some(n) => format!("image {i} '{n}'"),
            None => format!("image {i}"),
        };
        let err = |what: String| src.err(format!("{who}: {label}: {what}"));
        let unsupported = |kind: &str, warnings: &mut Vec<String>| -> Result<Option<Decoded>, SceneError> {
            warnings.push(format!(
                "{}: {who}: {label}: {kind} images are not supported (only PNG and JPEG); the base colour factor is used alone",
                src.name()
            ));
            Ok(None)
        };
        // The declared type: `mimeType`, else the media type of a data URI.
        let declared = match (&img.mime_type, &img.uri) {
            (Some(m), _) => m.0.trim().to_ascii_lowercase(),
            (None, Some(uri)) if uri.starts_with("data:") => gltf_read::data_uri_media_type(uri),
            _ => String::new(),
        };
        match declared.as_str() {
            "" | "image/png" | "image/jpeg" | "image/jpg" | "application/octet-stream" => {}
            other => return unsupported(&format!("'{other}'"), warnings),
        }
        let bytes: Cow<[u8]> = match (&img.buffer_view, &img.uri) {
            (Some(view), _) => Cow::Borrowed(self.doc.view_bytes(src, &format!("{who}: {label}"), view.value())?),
            (None, Some(uri)) if uri.starts_with("data:") => {
                Cow::Owned(gltf_read::decode_data_uri(src, &format!("{who}: {label}"), uri)?)
            }
            (None, Some(uri)) => {
                if uri.contains("://") {
                    return Err(err(format!(
                        "remote uri '{uri}' is not supported (only relative file paths and data URIs)"
                    )));
                }
                let file = src.dir().join(gltf_read::percent_decode(uri));
                Cow::Owned(std::fs::read(&file).map_err(|e| err(format!("cannot read '{}': {e}", file.display())))?)
            }
            (None, None) => return Err(err("has neither a uri nor a bufferView".into())),
        };
        let format = if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            image::ImageFormat::Png
        } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
            image::ImageFormat::Jpeg
        } else if bytes.starts_with(b"\xabKTX 20\xbb\r\n\x1a\n") {
            return unsupported("KTX2", warnings);
        } else if let Ok(f) = image::guess_format(&bytes) {
            return unsupported(&format!("{f:?}"), warnings);
        } else {
            return Err(err(format!(
                "cannot decode: not a PNG or JPEG image ({} bytes starting {:02x?})",
                bytes.len(),
                &bytes[..bytes.len().min(8)]
            )));
        };
        let (width, height, texels) = decode(&bytes, format).map_err(|e| err(format!("cannot decode: {e}")))?;
        Ok(Some(Decoded {
            label,
            width,
            height,
            texels: texels.into(),
        }))
    }
}

/// Decodes a PNG or JPEG into linear texels with the exact sRGB EOTF (alpha dropped, grey
/// expanded to RGB, 16-bit channels kept at full precision).
fn decode(bytes: &[u8], format: image::ImageFormat) -> Result<(u32, u32, Vec<Rgb>), String> {
    use image::ColorType;
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(|e| e.to_string())?;
    let (width, height) = image::ImageDecoder::dimensions(&decoder);
    if width as u64 * height as u64 > MAX_TEXELS {
        return Err(format!("{width}x{height} is too large (at most {MAX_TEXELS} texels)"));
    }
    let img = image::DynamicImage::from_decoder(decoder).map_err(|e| e.to_string())?;
    if img.width() == 0 || img.height() == 0 {
        return Err(format!("the image is empty ({}x{})", img.width(), img.height()));
    }
    let sixteen = matches!(
        img.color(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16
    );
    let (width, height) = (img.width(), img.height());
    let texels = if sixteen {
        let lut: Vec<f32> = (0..=u16::MAX)
            .map(|c| srgb_to_linear(c as f64 / 65535.0) as f32)
            .collect();
        let buf = img.into_rgb16();
        buf.pixels()
            .map(|p| Rgb::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]))
            .collect()
    } else {
        let lut: Vec<f32> = (0..=u8::MAX).map(|c| srgb_to_linear(c as f64 / 255.0) as f32).collect();
        let buf = img.into_rgb8();
        buf.pixels()
            .map(|p| Rgb::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]))
            .collect()
    };
    Ok((width, height, texels))
}
