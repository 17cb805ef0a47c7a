//! Reading the glTF container (JSON or GLB), its buffers and accessors, with every size and
//! offset checked so that bad files give errors, never panics.
use super::Src;
use crate::SceneError;
use base64::Engine as _;
use gltf::json::{self, accessor::ComponentType, accessor::Type, validation::Checked};
use std::path::Path;

/// The glTF extensions whose meaning we implement (all others are ignored with a warning, or
/// rejected when listed in `extensionsRequired`).
pub(super) const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
];

/// Largest accessor without a bufferView (zeros plus sparse values) we allocate.
const MAX_UNBACKED_BYTES: u64 = 1 << 30;

/// A parsed, validated glTF document with its buffers in memory.
pub(super) struct GltfDoc {
    pub root: json::Root,
    pub buffers: Vec<Vec<u8>>,
}

/// Parses a `.gltf` or `.glb` file's bytes and loads its buffers (relative to `src.path`).
pub(super) fn read_gltf(src: &Src, bytes: &[u8], warnings: &mut Vec<String>) -> Result<GltfDoc, SceneError> {
    if bytes.is_empty() {
        return Err(src.err("empty file (expected glTF JSON or a binary .glb)"));
    }
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        parse_glb(src, bytes)?
    } else {
        (bytes, None)
    };
    let root: json::Root =
        json::deserialize::from_slice(json_bytes).map_err(|e| src.err(format!("malformed glTF JSON: {e}")))?;

    if !root.asset.version.starts_with("2.") {
        return Err(src.err(format!(
            "glTF version '{}' is not supported (expected 2.x)",
            root.asset.version
        )));
    }
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(src.err(format!(
                "required extension '{ext}' is not supported (supported: {})",
                SUPPORTED_EXTENSIONS.join(", ")
            )));
        }
    }
    for ext in &root.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(format!(
                "{}: extension '{ext}' is not supported and is ignored",
                src.name()
            ));
        }
    }
    // The gltf crate's validation hook for primitives indexes the POSITION accessor before the
    // range check runs (found by `cargo xtask fuzz`): check every accessor a primitive names
    // first, and keep a guard for any other such panic.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let named = prim.attributes.values().chain(&prim.indices).chain(
                prim.targets
                    .iter()
                    .flatten()
                    .flat_map(|t| t.positions.iter().chain(&t.normals).chain(&t.tangents)),
            );
            for a in named {
                if a.value() >= root.accessors.len() {
                    return Err(src.err(format!(
                        "invalid glTF: mesh {m} primitive {p} names accessor {} (there are {})",
                        a.value(),
                        root.accessors.len()
                    )));
                }
            }
        }
    }
    // The gltf crate's own validation: indices in range, required properties present, enum
    // values known. Its accessors may panic on documents that fail it.
    let validated = std::panic::catch_unwind(move || gltf::Document::from_json(root))
        .map_err(|_| src.err("invalid glTF: the glTF validator failed on this document"))?;
    let root = match validated {
        Ok(doc) => doc.into_json(),
        Err(gltf::Error::Validation(errors)) => {
            let list: Vec<String> = errors.iter().take(8).map(|(path, e)| format!("{path}: {e}")).collect();
            let more = if errors.len() > 8 {
                format!(" (and {} more)", errors.len() - 8)
            } else {
                String::new()
            };
            return Err(src.err(format!("invalid glTF: {}{more}", list.join("; "))));
        }
        Err(e) => return Err(src.err(format!("invalid glTF: {e}"))),
    };

    let mut buffers = Vec::with_capacity(root.buffers.len());
    let mut bin = bin;
    for (i, b) in root.buffers.iter().enumerate() {
        let label = match &b.name {
            Some(n) => format!("buffer {i} ('{n}')"),
            None => format!("buffer {i}"),
        };
        let (data, origin) = match &b.uri {
            None => match (i, bin.take()) {
                (0, Some(bin)) => (bin.to_vec(), "the GLB BIN chunk".to_string()),
                _ => {
                    return Err(src.err(format!("{label} has no uri and there is no GLB BIN chunk for it")));
                }
            },
            Some(uri) if uri.starts_with("data:") => (decode_data_uri(src, &label, uri)?, "its data URI".to_string()),
            Some(uri) => {
                if uri.contains("://") {
                    return Err(src.err(format!(
                        "{label}: remote uri '{uri}' is not supported (only relative file paths and data URIs)"
                    )));
                }
                let rel = percent_decode(uri);
                let file = src.dir().join(&rel);
                let data = std::fs::read(&file)
                    .map_err(|e| src.err(format!("{label}: cannot read '{}': {e}", file.display())))?;
                (data, format!("'{rel}'"))
            }
        };
        let need = b.byte_length.0;
        if (data.len() as u64) < need {
            return Err(src.err(format!(
                "{label}: byteLength is {need} but {origin} holds only {} bytes (truncated file?)",
                data.len()
            )));
        }
        buffers.push(data);
    }
    Ok(GltfDoc { root, buffers })
}

/// Splits a GLB container into its JSON chunk and optional BIN chunk.
fn parse_glb<'a>(src: &Src, bytes: &'a [u8]) -> Result<(&'a [u8], Option<&'a [u8]>), SceneError> {
    let word = |at: usize| -> Option<u32> { Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?)) };
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err(src.err(format!(
            "truncated GLB: {} bytes, shorter than the 12-byte header",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(src.err(format!("GLB container version {version} is not supported (expected 2)")));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(src.err(format!(
            "truncated GLB: the header says {length} bytes but the file has {}",
            bytes.len()
        )));
    }
    let bytes = &bytes[..length];
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0;
    while at < bytes.len() {
        let (Some(len), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(src.err(format!("truncated GLB: chunk {chunk} header at byte {at} is cut off")));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                src.err(format!(
                    "truncated GLB: chunk {chunk} claims {len} bytes but only {} remain",
                    bytes.len().saturating_sub(start)
                ))
            })?;
        let data = &bytes[start..end];
        match (chunk, kind) {
            (0, 0x4E4F_534A) => json = Some(data),
            (0, _) => return Err(src.err("malformed GLB: the first chunk is not JSON")),
            (1, 0x004E_4942) => bin = Some(data),
            _ => {} // unknown chunk types are skipped, as the spec asks
        }
        at = (end + 3) & !3;
        chunk += 1;
    }
    let json = json.ok_or_else(|| src.err("malformed GLB: no JSON chunk"))?;
    Ok((json, bin))
}

/// The media type of a `data:` URI (`image/png` in `data:image/png;base64,...`), lower case;
/// empty when it has none.
pub(super) fn data_uri_media_type(uri: &str) -> String {
    let header = uri.split(',').next().unwrap_or("");
    let header = header.strip_prefix("data:").unwrap_or(header);
    header.split(';').next().unwrap_or("").trim().to_ascii_lowercase()
}

pub(super) fn decode_data_uri(src: &Src, label: &str, uri: &str) -> Result<Vec<u8>, SceneError> {
    let Some(comma) = uri.find(',') else {
        return Err(src.err(format!("{label}: malformed data URI (no ',')")));
    };
    let (header, payload) = (&uri[..comma], &uri[comma + 1..]);
    if !header.ends_with(";base64") {
        return Err(src.err(format!("{label}: only base64 data URIs are supported")));
    }
    base64::engine::general_purpose::STANDARD
        .decode(payload.trim())
        .map_err(|e| src.err(format!("{label}: malformed base64 in data URI: {e}")))
}

/// Decodes `%XX` escapes in a relative URI (e.g. `%20` for a space).
pub(super) fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

impl GltfDoc {
    /// Bytes `[offset, offset + stride*(count-1) + elem)` of buffer view `view`, checked against
    /// the view and the buffer; returns (view bytes from offset, stride).
    fn view_range(
        &self,
        src: &Src,
        what: &str,
        view: usize,
        offset: u64,
        count: u64,
        elem: usize,
        allow_stride: bool,
    ) -> Result<(&[u8], usize), SceneError> {
        let v = self
            .root
            .buffer_views
            .get(view)
            .ok_or_else(|| src.err(format!("{what}: bufferView {view} does not exist")))?;
        let buffer = self
            .buffers
            .get(v.buffer.value())
            .ok_or_else(|| src.err(format!("{what}: bufferView {view} names a missing buffer")))?;
        let view_off = v.byte_offset.map_or(0, |o| o.0);
        let view_len = v.byte_length.0;
        let view_end = view_off.saturating_add(view_len);
        let declared = self.root.buffers[v.buffer.value()].byte_length.0;
        if view_end > declared || view_end > buffer.len() as u64 {
            return Err(src.err(format!(
                "{what}: bufferView {view} (bytes {view_off}..{view_end}) extends past the end of buffer {} ({} bytes)",
                v.buffer.value(),
                declared.min(buffer.len() as u64)
            )));
        }
        let stride = match v.byte_stride {
            Some(s) if allow_stride => s.0,
            _ => elem,
        };
        if stride < elem {
            return Err(src.err(format!(
                "{what}: bufferView {view} byteStride {stride} is smaller than an element ({elem} bytes)"
            )));
        }
        let need = if count == 0 {
            0
        } else {
            (count - 1)
                .checked_mul(stride as u64)
                .and_then(|x| x.checked_add(elem as u64))
                .unwrap_or(u64::MAX)
        };
        let end = offset.saturating_add(need);
        if end > view_len {
            return Err(src.err(format!(
                "{what}: needs bytes {offset}..{end} of bufferView {view}, which has only {view_len} bytes ({count} elements of {elem} bytes, stride {stride})"
            )));
        }
        let start = (view_off + offset) as usize;
        Ok((&buffer[start..(view_off + view_len) as usize], stride))
    }

    /// Reads accessor `index` as packed elements of `elem` bytes (applying sparse substitution),
    /// checking its type. Returns (component type, packed bytes, count).
    fn accessor_bytes(
        &self,
        src: &Src,
        what: &str,
        index: usize,
        want: Type,
        allowed: &[ComponentType],
    ) -> Result<(ComponentType, Vec<u8>, usize), SceneError> {
        let a = self
            .root
            .accessors
            .get(index)
            .ok_or_else(|| src.err(format!("{what}: accessor {index} does not exist")))?;
        let (Checked::Valid(ct), Checked::Valid(ty)) = (&a.component_type, &a.type_) else {
            return Err(src.err(format!("{what}: accessor {index} has an invalid type")));
        };
        let ct = ct.0;
        let ty = *ty;
        if ty != want || !allowed.contains(&ct) {
            let allowed: Vec<&str> = allowed.iter().map(|c| component_name(*c)).collect();
            return Err(src.err(format!(
                "{what}: accessor {index} is {} {}, expected {} of {}",
                component_name(ct),
                type_name(ty),
                type_name(want),
                allowed.join("/")
            )));
        }
        let comps = match ty {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 => 4,
            _ => unreachable!("only scalar and vector accessors are requested"),
        };
        let elem = comps * component_size(ct);
        let count = a.count.0;
        if count > (1u64 << 31) {
            return Err(src.err(format!("{what}: accessor {index} count {count} is absurdly large")));
        }
        let what_acc = format!("{what}: accessor {index}");
        // Check the data exists before allocating: a view-backed accessor is then bounded by
        // the file's size; one without a view (all zeros + sparse values) gets a sane cap.
        let backing = match a.buffer_view {
            Some(view) => {
                let offset = a.byte_offset.map_or(0, |o| o.0);
                Some(self.view_range(src, &what_acc, view.value(), offset, count, elem, true)?)
            }
            None if count * elem as u64 > MAX_UNBACKED_BYTES => {
                return Err(src.err(format!(
                    "{what_acc}: {count} elements without a bufferView is too large"
                )));
            }
            None => None,
        };
        let mut out = vec![0u8; count as usize * elem];
        if let Some((data, stride)) = backing {
            for i in 0..count as usize {
                out[i * elem..(i + 1) * elem].copy_from_slice(&data[i * stride..i * stride + elem]);
            }
        }
        if let Some(sparse) = &a.sparse {
            let n = sparse.count.0;
            if n > count {
                return Err(src.err(format!(
                    "{what_acc}: sparse count {n} exceeds the accessor count {count}"
                )));
            }
            let Checked::Valid(ict) = &sparse.indices.component_type else {
                return Err(src.err(format!("{what_acc}: sparse indices have an invalid component type")));
            };
            let isz = component_size(ict.0);
            let (idata, _) = self.view_range(
                src,
                &format!("{what_acc} sparse indices"),
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                n,
                isz,
                false,
            )?;
            let (vdata, _) = self.view_range(
                src,
                &format!("{what_acc} sparse values"),
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                n,
                elem,
                false,
            )?;
            for k in 0..n as usize {
                let target = read_uint(ict.0, &idata[k * isz..]) as usize;
                if target >= count as usize {
                    return Err(src.err(format!(
                        "{what_acc}: sparse index {target} out of range ({count} elements)"
                    )));
                }
                out[target * elem..(target + 1) * elem].copy_from_slice(&vdata[k * elem..(k + 1) * elem]);
            }
        }
        Ok((ct, out, count as usize))
    }

    /// A `VEC3` `FLOAT` accessor (positions, normals).
    pub fn read_vec3(&self, src: &Src, what: &str, index: usize) -> Result<Vec<[f32; 3]>, SceneError> {
        let (_, bytes, count) = self.accessor_bytes(src, what, index, Type::Vec3, &[ComponentType::F32])?;
        let f = |i: usize| f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
        Ok((0..count).map(|i| [f(3 * i), f(3 * i + 1), f(3 * i + 2)]).collect())
    }

    /// A `VEC2` texture-coordinate accessor: `FLOAT`, or normalized `UNSIGNED_BYTE` /
    /// `UNSIGNED_SHORT` (divided by 255 / 65535), as the glTF specification allows for
    /// `TEXCOORD_n`.
    pub fn read_texcoords(&self, src: &Src, what: &str, index: usize) -> Result<Vec<[f32; 2]>, SceneError> {
        let allowed = [ComponentType::F32, ComponentType::U8, ComponentType::U16];
        let (ct, bytes, count) = self.accessor_bytes(src, what, index, Type::Vec2, &allowed)?;
        if ct != ComponentType::F32 && !self.root.accessors[index].normalized {
            return Err(src.err(format!(
                "{what}: accessor {index} is {} VEC2 but not normalized (integer texture coordinates need KHR_mesh_quantization, which is not supported)",
                component_name(ct)
            )));
        }
        let sz = component_size(ct);
        let c = |i: usize| -> f32 {
            let b = &bytes[i * sz..];
            match ct {
                ComponentType::U8 => b[0] as f32 / 255.0,
                ComponentType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
                _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            }
        };
        Ok((0..count).map(|i| [c(2 * i), c(2 * i + 1)]).collect())
    }

    /// All bytes of buffer view `view` (an image), checked against its buffer.
    pub fn view_bytes(&self, src: &Src, what: &str, view: usize) -> Result<&[u8], SceneError> {
        let len = self
            .root
            .buffer_views
            .get(view)
            .ok_or_else(|| src.err(format!("{what}: bufferView {view} does not exist")))?
            .byte_length
            .0;
        let len = usize::try_from(len).map_err(|_| src.err(format!("{what}: bufferView {view} is too large")))?;
        let (bytes, _) = self.view_range(src, what, view, 0, 1, len, false)?;
        Ok(&bytes[..len])
    }

    /// A `SCALAR` accessor of unsigned byte/short/int (indices).
    pub fn read_indices(&self, src: &Src, what: &str, index: usize) -> Result<Vec<u32>, SceneError> {
        let allowed = [ComponentType::U8, ComponentType::U16, ComponentType::U32];
        let (ct, bytes, count) = self.accessor_bytes(src, what, index, Type::Scalar, &allowed)?;
        let sz = component_size(ct);
        Ok((0..count).map(|i| read_uint(ct, &bytes[i * sz..])).collect())
    }
}

fn read_uint(ct: ComponentType, b: &[u8]) -> u32 {
    match ct {
        ComponentType::U8 | ComponentType::I8 => b[0] as u32,
        ComponentType::U16 | ComponentType::I16 => u16::from_le_bytes([b[0], b[1]]) as u32,
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// The file name of a path, for short messages.
pub(super) fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}
