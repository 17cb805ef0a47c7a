//! Image files: OpenEXR (float32 linear RGB, with render metadata) and PNG previews, written
//! atomically (temporary file in the same directory, fsync, rename) so a reader never sees a
//! partial file.
use crate::Image;
use beamlight_scene::Rgb;
use std::{
    io::{Cursor, Write},
    path::{Path, PathBuf},
};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
}

fn err(path: &Path, message: impl ToString) -> OutputError {
    OutputError::File {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| err(path, "not a file name"))?;
    let tmp = dir.join(format!(".{}.tmp{}", name.to_string_lossy(), std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        err(path, format!("cannot write: {e}"))
    })
}

/// Writes a float32 RGB OpenEXR with `metadata` as string header attributes.
pub fn write_exr(path: &Path, image: &Image, metadata: &[(&str, String)]) -> Result<(), OutputError> {
    write_exr_layers(path, image, &[], metadata)
}

/// Writes a render's films: the beauty's mean and one layer per component film (in
/// `Component::ALL` order, named as the components; none when `components` is empty), with
/// the pass count, rejected samples and discarded estimates in the header before `metadata`.
/// What `render` and `merge` both write.
pub fn write_films(
    path: &Path,
    film: &crate::Film,
    components: &[crate::Film],
    discarded: &crate::many_lights::Discards,
    metadata: &[(&str, String)],
) -> Result<Image, OutputError> {
    let image = film.image();
    let layers: Vec<(&str, Image)> = beamlight_trace::components::Component::ALL
        .iter()
        .zip(components)
        .map(|(c, f)| (c.name(), f.image()))
        .collect();
    let named: Vec<(&str, &Image)> = layers.iter().map(|(n, i)| (*n, i)).collect();
    let mut header = vec![
        ("beamlight.passes", film.passes().to_string()),
        ("beamlight.spp", film.samples.to_string()),
        ("beamlight.rejected_samples", film.rejected.to_string()),
        ("beamlight.discarded_estimates", discarded.to_string()),
    ];
    if film.partial_passes() > 0 {
        // A time budget's last pass, shortened to a share of the pixels: those have one sample
        // more than `beamlight.spp`.
        header.push(("beamlight.partial_passes", film.partial_passes().to_string()));
    }
    header.extend(metadata.iter().cloned());
    write_exr_layers(path, &image, &named, &header)?;
    Ok(image)
}

/// Writes a float32 OpenEXR whose first layer is the beauty image and whose further layers are
/// `layers` (each R, G, B), with `metadata` as string header attributes of the beauty layer.
/// With extra layers the file is multi-part and the beauty part is named "beauty".
pub fn write_exr_layers(
    path: &Path,
    beauty: &Image,
    layers: &[(&str, &Image)],
    metadata: &[(&str, String)],
) -> Result<(), OutputError> {
    use exr::{meta::attribute::*, prelude::*};
    if let Some((name, _)) = layers
        .iter()
        .find(|(_, l)| (l.width, l.height) != (beauty.width, beauty.height))
    {
        return Err(err(path, format!("layer '{name}' differs in size from the image")));
    }
    // A file with several layers is multi-part, where every part needs a name.
    let mut attrs = match layers.is_empty() {
        true => LayerAttributes::default(),
        false => LayerAttributes::named("beauty"),
    };
    attrs.software_name = Some(Text::from("beamlight"));
    for (k, v) in metadata {
        attrs
            .other
            .insert(Text::from(*k), AttributeValue::Text(Text::from(v.as_str())));
    }
    // The exr crate's type for an RGB layer read through a closure.
    #[allow(clippy::type_complexity)]
    fn rgb_layer(
        image: &crate::Image,
        attrs: LayerAttributes,
    ) -> Layer<SpecificChannels<impl Fn(Vec2<usize>) -> (f32, f32, f32) + Sync + '_, RgbChannels>> {
        let w = image.width as usize;
        let channels = SpecificChannels::rgb(move |pos: Vec2<usize>| {
            let p = image.pixels[pos.y() * w + pos.x()];
            (p.x, p.y, p.z)
        });
        Layer::new((w, image.height as usize), attrs, Encoding::SMALL_LOSSLESS, channels)
    }
    let mut all = vec![rgb_layer(beauty, attrs)];
    for (name, image) in layers {
        all.push(rgb_layer(image, LayerAttributes::named(*name)));
    }
    let mut bytes = Cursor::new(Vec::new());
    Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((
            beauty.width as usize,
            beauty.height as usize,
        ))),
        all,
    )
    .write()
    .to_buffered(&mut bytes)
    .map_err(|e| err(path, e))?;
    write_atomic(path, bytes.get_ref())
}

/// Reads every RGB layer of an OpenEXR file by name ("" for an unnamed single layer).
pub fn read_exr_layers(path: &Path) -> Result<Vec<(String, crate::Image)>, OutputError> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| (res.width(), vec![Rgb::ZERO; res.width() * res.height()]),
            |px: &mut (usize, Vec<Rgb>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px.1[pos.y() * px.0 + pos.x()] = Rgb::new(r, g, b)
            },
        )
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| err(path, format!("cannot read OpenEXR: {e}")))?;
    Ok(img
        .layer_data
        .into_iter()
        .map(|l| {
            let name = l.attributes.layer_name.map(|n| n.to_string()).unwrap_or_default();
            let (w, h) = (l.size.width() as u32, l.size.height() as u32);
            (
                name,
                crate::Image {
                    width: w,
                    height: h,
                    pixels: l.channel_data.pixels.1,
                },
            )
        })
        .collect())
}

/// Reads the first RGB(A) layer of an OpenEXR file, with its string header attributes.
pub fn read_exr(path: &Path) -> Result<(Image, Vec<(String, String)>), OutputError> {
    use exr::prelude::*;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![Rgb::ZERO; res.width() * res.height()]),
        |px: &mut (usize, Vec<Rgb>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px.1[pos.y() * px.0 + pos.x()] = Rgb::new(r, g, b)
        },
    )
    .map_err(|e| err(path, format!("cannot read OpenEXR: {e}")))?;
    let size = img.layer_data.size;
    let mut meta = Vec::new();
    for (k, v) in &img.layer_data.attributes.other {
        if let exr::meta::attribute::AttributeValue::Text(t) = v {
            meta.push((k.to_string(), t.to_string()));
        }
    }
    meta.sort();
    let pixels = img.layer_data.channel_data.pixels.1;
    Ok((
        crate::Image {
            width: size.width() as u32,
            height: size.height() as u32,
            pixels,
        },
        meta,
    ))
}

/// Writes an 8-bit sRGB PNG preview: radiance × 2^exposure, clamped, sRGB-encoded.
pub fn write_png(path: &Path, image: &Image, exposure: f32) -> Result<(), OutputError> {
    let scale = exposure.exp2();
    let mut buf = Vec::with_capacity(image.pixels.len() * 3);
    for p in &image.pixels {
        for c in 0..3 {
            buf.push((srgb_encode(p[c] * scale) * 255.0 + 0.5) as u8);
        }
    }
    write_png_rgb8(path, image.width, image.height, buf)
}

/// Writes 8-bit RGB rows (already display-encoded) as a PNG, atomically.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: Vec<u8>) -> Result<(), OutputError> {
    let rgb = image::RgbImage::from_raw(width, height, rgb).ok_or_else(|| err(path, "bad image size"))?;
    let mut bytes = Cursor::new(Vec::new());
    rgb.write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| err(path, e))?;
    write_atomic(path, bytes.get_ref())
}

/// Linear → sRGB transfer function, input clamped to [0, 1] (NaN → 0).
pub fn srgb_encode(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_keeps_values_and_metadata() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let mut img = Image::new(5, 3);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Rgb::new(i as f32, 0.5 / (i + 1) as f32, 1e-7 * i as f32);
        }
        write_exr(
            &path,
            &img,
            &[("beamlight.method", "pt".into()), ("beamlight.spp", "16".into())],
        )
        .unwrap();
        let (back, meta) = read_exr(&path).unwrap();
        assert_eq!(back, img);
        assert!(meta.contains(&("beamlight.method".into(), "pt".into())));
        // No temporary file left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn component_layers_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("layers.exr");
        let mut beauty = Image::new(3, 2);
        beauty.pixels[4] = Rgb::new(1.0, 2.0, 3.0);
        let mut direct = Image::new(3, 2);
        direct.pixels[1] = Rgb::new(0.5, 0.25, 0.125);
        write_exr_layers(&path, &beauty, &[("direct", &direct), ("Lss", &Image::new(3, 2))], &[]).unwrap();
        let layers = read_exr_layers(&path).unwrap();
        let names: Vec<&str> = layers.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["beauty", "direct", "Lss"]);
        assert_eq!(layers[0].1, beauty);
        assert_eq!(layers[1].1, direct);
        // Readers that take the first layer get the beauty image.
        assert_eq!(read_exr(&path).unwrap().0, beauty);
    }

    #[test]
    fn unwritable_path_names_the_file() {
        let e = write_exr(Path::new("/nonexistent-dir/x.exr"), &Image::new(1, 1), &[]).unwrap_err();
        assert!(e.to_string().contains("/nonexistent-dir/x.exr"));
    }
}
