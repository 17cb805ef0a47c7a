//! Scene loading: a TOML sidecar naming a glTF 2.0 file, or a `.gltf`/`.glb` file alone.
//!
//! Every problem in the input becomes a [`SceneError`] naming the file (and, for TOML, the line
//! and column; for glTF, the element such as `mesh 'Statue' primitive 0`). Loading never panics
//! on bad input. Harmless things that are ignored (textures other than the base colour's,
//! images in unsupported formats, animations, skins, morph targets, unsupported optional
//! extensions, light `range`, degenerate triangles…) produce one entry each in
//! [`Scene::warnings`].
//!
//! # The sidecar (`.toml`)
//!
//! ```toml
//! gltf = "cornell.gltf"          # relative to this file (required)
//!
//! [render]
//! width = 256                    # 1..=16384
//! height = 256                   # 1..=16384
//! camera = "Camera"              # glTF camera node name (or camera name); default: first camera
//!
//! [[media]]                      # any number of media, at most one "global"
//! name = "fog"                   # unique
//! region = "global"              # "global" or the name of a closed glTF mesh
//! sigma_s = [0.3, 0.3, 0.3]      # 1/scene unit, finite, >= 0 (a single number means grey)
//! sigma_a = [0.02, 0.02, 0.02]   # default 0
//! g = 0.0                        # Henyey–Greenstein, -1 < g < 1, default 0
//! density = { grid = "smoke.bgrid", bounds = [[-1, 0, -1], [1, 2, 1]] }   # optional, or
//! # density = { grid = "smoke.vdb", name = "density" }                    # OpenVDB, or
//! # density = { perlin = { scale = 4.0, octaves = 4, height_falloff = 1.5, seed = 7 },
//! #             resolution = 64, bounds = [[-1, 0, -1], [1, 2, 1]] }    # procedural
//!
//! [materials.Statue]             # override by glTF material name
//! kind = "phong"                 # lambert | phong | mirror | glass
//! diffuse = [0.1, 0.1, 0.1]
//! specular = [0.8, 0.8, 0.8]
//! exponent = 80
//! ```
//!
//! Unknown keys anywhere are errors, and so are values of the wrong type (the message carries
//! the TOML line and column).
//!
//! ## Render settings and their defaults
//! * `width`/`height` given: used as they are (each must be 1..=16384).
//! * Neither given (and always for a glTF file alone): 512 pixels high, and
//!   `round(512 × aspectRatio)` wide when the chosen glTF camera has an `aspectRatio`, else 512.
//! * Only one given: the other follows from the camera's `aspectRatio` (square without one).
//!
//! ## Material overrides (`[materials.NAME]`)
//! `NAME` is a glTF material name (every material of that name is overridden; an unknown name
//! is an error listing the available names). Keys:
//! * `kind = "lambert"`: `albedo` (or `diffuse`), default the glTF base colour — including its
//!   `baseColorTexture`; an explicit `albedo` wins and the texture is dropped.
//! * `kind = "phong"`: `diffuse` (default the glTF base colour, texture included; an explicit
//!   `diffuse` drops the texture), `specular` and `exponent` (both required);
//!   `diffuse + specular` must be ≤ 1 in every channel (energy conservation), where with a
//!   texture `diffuse` is the base colour factor × the texture's brightest texel.
//! * `kind = "mirror"`: `reflectance`, default 1 (no texture).
//! * `kind = "glass"`: `ior` (> 0, default 1.5), `tint` (default 1; no texture).
//! * Any kind, or no `kind` at all (then only these two keys may appear): `emission = [r, g, b]`
//!   replaces the glTF emission, `double_sided = true|false` replaces `doubleSided`.
//!
//! Colours may be written `[r, g, b]` or as one number. Albedo-like colours must lie in [0, 1].
//!
//! ## Media
//! * `region = "global"`: the medium fills all space not inside a region mesh (the camera is
//!   then usually in it). At most one global medium.
//! * `region = "MeshName"`: the interior of a closed glTF mesh (looked up by mesh name, then by
//!   the name of a node that has a mesh). Every instance of that mesh in the scene must be
//!   closed: after welding vertices with identical positions, every edge is shared by exactly two
//!   triangles that traverse it in opposite directions (watertight, manifold, consistently
//!   oriented). A region mesh whose triangles face inward (negative signed volume) is flipped —
//!   winding and shading normals reversed — with a warning, so that afterwards the geometric
//!   normal of every region triangle points out of its medium. A mesh bounds at most one medium.
//! * Region triangles get `interface = Some(MediumInterface { inside: this medium, outside })`
//!   where `outside` is the medium of the innermost other region instance containing this one
//!   (parity test from a point on its surface), else the global medium, else vacuum.
//! * A region primitive without a glTF material becomes an invisible, index-matched boundary
//!   (`Material { bsdf: None, .. }`, named `"<medium boundary>"`); elsewhere a primitive without
//!   a material gets the `"<default>"` Lambert material of albedo 1 (glTF's default material has
//!   baseColorFactor 1).
//! * `density = { grid = "file.bgrid", bounds = [[x0,y0,z0],[x1,y1,z1]] }` makes the medium
//!   heterogeneous (format: [`crate::medium::parse_grid`]); `bounds` defaults to the bounding
//!   box of the region mesh, or of all triangles for a global medium.
//! * `density = { grid = "file.vdb", name = "density" }`: an OpenVDB float grid (`name`
//!   defaults to "density"; an unknown name is an error listing the grids in the file; a
//!   non-float grid, a corrupt or truncated file are errors naming the file). Its active
//!   voxels are copied voxel for voxel into a dense grid (at most 2²⁴ voxels) with one voxel
//!   of background (0) around them, placed in the world by the grid's own transform (voxel
//!   size and translation; rotating/affine maps are rejected) — see [`crate::vdb`]. An
//!   explicit `bounds` instead places the outer faces of the active voxels' index box there.
//! * `density = { perlin = { … }, resolution = 64, bounds = … }`: a procedural density baked
//!   into a grid of `resolution` voxels (an integer or `[nx, ny, nz]`, 1..=4096 per axis, at
//!   most 2²⁴ in all; default 64), over `bounds` (default as for `grid`). With `u` the
//!   position normalised to the bounds and `h = u.y`:
//!   `d = max(0, bias + amplitude·fbm(scale·u)) · exp(−height_falloff·h)` where fbm is the
//!   weight-normalised sum of `octaves` Perlin octaves (frequency ×`lacunarity`, amplitude
//!   ×`gain` per octave). Keys and defaults: `scale` 4 (> 0), `octaves` 4 (1..=16), `gain`
//!   0.5 (0..=4), `lacunarity` 2 (> 0, ≤ 16), `height_falloff` 1.5 (−50..=50), `bias` 0.5,
//!   `amplitude` 2.5, `seed` 0 (0..=2³²−1); `perlin = {}` is a cloudy medium of mean
//!   density ≈ 0.5 at the bottom fading to ≈ 0.1 at the top. Exact definitions and
//!   determinism: [`crate::noise`].
//!
//! # glTF
//! * The default scene (`scene`), else the first scene, else every parentless node (with a
//!   warning). World transforms are accumulated over the node hierarchy; a node reachable twice
//!   (cycle, or several parents) is an error.
//! * Primitives in mode TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN (others are skipped with a
//!   warning); indices u8/u16/u32 or none; positions and normals must be `FLOAT VEC3`
//!   (sparse accessors are supported, `KHR_mesh_quantization` is not).
//! * A non-finite vertex position is an error; zero-area triangles are skipped (one warning per
//!   mesh with the count). With `NORMAL`, shading normals are transformed by the inverse
//!   transpose and normalised; without, triangles are flat shaded. A transform with negative
//!   determinant swaps two vertices so the geometric normal keeps the orientation the glTF
//!   spec defines.
//! * Materials: `baseColorFactor` rgb (must lie in [0, 1]) × `baseColorTexture` → Lambert
//!   albedo (alpha ignored); `emissiveFactor × KHR_materials_emissive_strength` (finite, ≥ 0)
//!   → emission; `doubleSided`; `KHR_materials_transmission` factor > 0 → `Glass { ior:
//!   KHR_materials_ior (≥ 1, default 1.5), tint: baseColorFactor }` (a factor below 1 is
//!   treated as 1, with a warning; glass ignores `baseColorTexture`, with a warning). The
//!   other textures (metallic-roughness, normal, occlusion, emissive, transmission) are
//!   ignored with one warning per material; their images are never read.
//! * Base colour textures ([`crate::texture`] has the conventions): the factor stays in the
//!   material's BSDF and [`crate::bsdf::Material::base_color_texture`] indexes
//!   [`Scene::textures`]; [`Scene::bsdf_at`] multiplies them at a hit. Images come from a
//!   `bufferView` (GLB or embedded buffer), a base64 `data:` URI, or a file relative to the
//!   glTF (`%XX`-escaped); PNG (8 or 16 bits per channel, grey or RGB, alpha dropped) and
//!   JPEG are decoded, with the format taken from the bytes. They are sRGB-encoded and
//!   decoded to linear RGB with the exact sRGB EOTF. Another declared type (`mimeType` or
//!   data URI type, e.g. `image/ktx2`, `image/webp`) or content (WebP, KTX2, …) is a warning
//!   and the factor is used alone. A missing file or an image that does not decode is an
//!   error naming the material and the image (`image 2 'wood.png': cannot decode: …`);
//!   images larger than 16384 pixels a side or 2²⁶ texels are errors too. The sampler's
//!   `wrapS`/`wrapT` are used (default `REPEAT`); its filters are not (always bilinear).
//!   Materials using the same image with the same wrap modes share one texture.
//! * Texture coordinates: `TEXCOORD_n` as the `baseColorTexture`'s `texCoord` says, read only
//!   for primitives whose material uses a texture (only their triangles get
//!   [`crate::scene::Triangle::uv`]): `FLOAT VEC2`, or normalized `UNSIGNED_BYTE` /
//!   `UNSIGNED_SHORT` (c / 255, c / 65535; not normalized is an error); non-finite values are
//!   errors. A primitive without that attribute gets uv (0, 0) everywhere (what WebGL viewers
//!   show), with a warning.
//! * Cameras: perspective only (an orthographic camera that is asked for, or the only kind
//!   there is, is an error; an orthographic one skipped by the default choice is a warning).
//!   The camera node's world transform with scale removed (forward −Z and up +Y are kept,
//!   right is rebuilt so the frame is right-handed). With no camera at all, a default camera
//!   with yfov 40° looks down −Z at the centre of the bounding box of all triangles and
//!   lights, from distance r / sin(20°) (r = half the box diagonal, so the whole bounding sphere
//!   is in view), with a warning.
//! * `KHR_lights_punctual`: point, spot and directional lights, intensity × colour mapped 1:1
//!   (see [`crate::light`]); `range` is ignored with a warning.
//! * The document must also pass the `gltf` crate's validation (references in range,
//!   required properties present); buffers (GLB `BIN` chunk, base64 data URIs, or files
//!   relative to the glTF, `%XX`-escaped) must hold `byteLength` bytes, and every accessor,
//!   buffer view and sparse index is bounds-checked before it is read.
//! * `extensionsRequired` naming anything but `KHR_lights_punctual`,
//!   `KHR_materials_emissive_strength`, `KHR_materials_transmission` and `KHR_materials_ior`
//!   is an error.
// `!(x > y)` is deliberate throughout: it is also true for NaN, which must be rejected.

use crate::{Scene, SceneError};
use std::ops::Range;
use std::path::{Path, PathBuf};

mod build;
mod camera;
mod geometry;
mod gltf_read;
mod images;
mod lights;
mod materials;
mod media;
mod names;
mod nodes;
mod sidecar;
mod triangles;

/// Loads a scene from a TOML sidecar (`.toml`), or a `.gltf`/`.glb` file alone (then with the
/// default render settings). See the [module documentation](self) for the format, the defaults
/// and the conventions.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "toml" => {
            let text =
                String::from_utf8(bytes).map_err(|e| SceneError::invalid(path, format!("not UTF-8 text: {e}")))?;
            let toml = TomlSrc {
                src: Src::new(path),
                text,
            };
            let sidecar: sidecar::Sidecar =
                toml::from_str(&toml.text).map_err(|e| toml.src.err(e.to_string().trim_end().to_string()))?;
            let gltf_path = toml.src.dir().join(sidecar.gltf.get_ref());
            let gltf_bytes = std::fs::read(&gltf_path).map_err(|e| {
                toml.err_at(
                    sidecar.gltf.span(),
                    format!(
                        "gltf = \"{}\": cannot read '{}': {e}",
                        sidecar.gltf.get_ref(),
                        gltf_path.display()
                    ),
                )
            })?;
            build::build_scene(Src::new(&gltf_path), &gltf_bytes, Some((&toml, &sidecar)), path)
        }
        "gltf" | "glb" => build::build_scene(Src::new(path), &bytes, None, path),
        _ => Err(SceneError::invalid(
            path,
            format!("unknown scene file type '.{ext}' (expected a .toml sidecar, .gltf or .glb)"),
        )),
    }
}

/// A file that errors are about.
pub(super) struct Src {
    path: PathBuf,
}

impl Src {
    fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
        }
    }
    fn err(&self, what: impl Into<String>) -> SceneError {
        SceneError::invalid(&self.path, what)
    }
    fn name(&self) -> String {
        gltf_read::file_name(&self.path)
    }
    fn dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new(""))
    }
}

/// The TOML sidecar's text, for locating spans.
pub(super) struct TomlSrc {
    src: Src,
    text: String,
}

impl TomlSrc {
    fn err_at(&self, span: Range<usize>, what: impl std::fmt::Display) -> SceneError {
        let (line, col) = sidecar::line_col(&self.text, span.start);
        self.src.err(format!("line {line}, column {col}: {what}"))
    }
}
