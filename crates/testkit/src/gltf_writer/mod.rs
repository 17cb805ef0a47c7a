//! A small glTF 2.0 writer for generated scenes (the bundled assets, tests, benchmarks).
//!
//! It writes exactly what [`beamlight_scene::load`] reads: triangle meshes (positions, optional normals
//! and `TEXCOORD_0`, indices of the smallest sufficient width by default), node transforms,
//! perspective cameras, metallic-roughness materials with an optional `baseColorTexture`
//! (an embedded PNG with its sampler's wrap modes), `KHR_materials_emissive_strength`,
//! `KHR_materials_transmission` and `KHR_materials_ior`, and `KHR_lights_punctual` lights.
//! Output is deterministic: the same calls give byte-identical files.
//!
//! ```no_run
//! use beamlight_testkit::gltf_writer::{GltfBuilder, MaterialDesc, shapes};
//! use glam::Vec3;
//! let mut b = GltfBuilder::new();
//! let white = b.material(MaterialDesc::lambert("White", [0.8, 0.8, 0.8]));
//! let (p, i) = shapes::quad(Vec3::new(-1.0, 0.0, 1.0), Vec3::X * 2.0, Vec3::NEG_Z * 2.0);
//! b.mesh("Floor", &p, &i, None, Some(white));
//! b.camera_look_at("Camera", Vec3::new(0.0, 1.0, 3.0), Vec3::Y, Vec3::Y, 0.7, None);
//! b.write_gltf(std::path::Path::new("floor.gltf")).unwrap();
//! ```
use base64::Engine as _;
use beamlight_scene::texture::Wrap;
use glam::{Mat3, Quat, Vec2, Vec3};
use serde_json::{Map, Value, json};
use std::path::Path;

pub mod shapes;

/// A metallic-roughness glTF material (metallic 0, roughness 1) and its extensions.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    pub name: String,
    /// `baseColorFactor` (alpha 1): the Lambert albedo, or the glass tint.
    pub base_color: [f32; 3],
    /// `emissiveFactor` (each in [0, 1] per the glTF schema; scale with `emissive_strength`).
    pub emissive: [f32; 3],
    /// `KHR_materials_emissive_strength` (written only when not 1).
    pub emissive_strength: f32,
    pub double_sided: bool,
    /// `KHR_materials_transmission` factor (written only when > 0): > 0 makes a smooth dielectric.
    pub transmission: f32,
    /// `KHR_materials_ior` (written when transmission > 0 or the value is not 1.5).
    pub ior: f32,
    /// `baseColorTexture` (reading `TEXCOORD_0`): a texture index returned by
    /// [`GltfBuilder::texture_png`]. It multiplies `base_color`.
    pub base_color_texture: Option<u32>,
}

impl MaterialDesc {
    /// A diffuse material with albedo `rgb`.
    pub fn lambert(name: &str, rgb: [f32; 3]) -> Self {
        Self {
            name: name.to_string(),
            base_color: rgb,
            emissive: [0.0; 3],
            emissive_strength: 1.0,
            double_sided: false,
            transmission: 0.0,
            ior: 1.5,
            base_color_texture: None,
        }
    }

    /// A black (non-reflecting), one-sided emitter of radiance `radiance` (any magnitude: the
    /// factor is normalised to ≤ 1 and the rest goes into `emissive_strength`).
    pub fn emitter(name: &str, radiance: [f32; 3]) -> Self {
        let mut m = Self::lambert(name, [0.0; 3]);
        m.set_emission(radiance);
        m
    }

    /// A clear smooth dielectric.
    pub fn glass(name: &str, ior: f32) -> Self {
        let mut m = Self::lambert(name, [1.0; 3]);
        m.transmission = 1.0;
        m.ior = ior;
        m
    }

    /// Sets `emissive`/`emissive_strength` so that their product is `radiance`.
    pub fn set_emission(&mut self, radiance: [f32; 3]) {
        let max = radiance.iter().copied().fold(0.0f32, f32::max);
        if max > 1.0 {
            self.emissive = radiance.map(|c| c / max);
            self.emissive_strength = max;
        } else {
            self.emissive = radiance;
            self.emissive_strength = 1.0;
        }
    }

    /// Builder-style [`MaterialDesc::set_emission`].
    pub fn with_emission(mut self, radiance: [f32; 3]) -> Self {
        self.set_emission(radiance);
        self
    }

    /// Builder-style `base_color_texture`.
    pub fn with_base_color_texture(mut self, texture: u32) -> Self {
        self.base_color_texture = Some(texture);
        self
    }

    /// Builder-style `double_sided`.
    pub fn with_double_sided(mut self, double_sided: bool) -> Self {
        self.double_sided = double_sided;
        self
    }
}

/// A node with a local TRS transform. Create with [`NodeDesc::new`] (identity transform).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeDesc {
    pub name: String,
    /// Mesh index returned by [`GltfBuilder::add_mesh`]/[`GltfBuilder::mesh`].
    pub mesh: Option<u32>,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    /// Node indices; a node listed as a child is not a scene root.
    pub children: Vec<u32>,
}

impl NodeDesc {
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            mesh: None,
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            children: Vec::new(),
        }
    }
    pub fn with_mesh(mut self, mesh: u32) -> Self {
        self.mesh = Some(mesh);
        self
    }
    pub fn with_translation(mut self, t: Vec3) -> Self {
        self.translation = t;
        self
    }
    pub fn with_rotation(mut self, r: Quat) -> Self {
        self.rotation = r;
        self
    }
    pub fn with_scale(mut self, s: Vec3) -> Self {
        self.scale = s;
        self
    }
    pub fn with_children(mut self, children: &[u32]) -> Self {
        self.children = children.to_vec();
        self
    }
}

/// Width of the index accessors the builder writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IndexWidth {
    /// The smallest of u8/u16/u32 that holds the largest index of each mesh.
    #[default]
    Auto,
    U8,
    U16,
    U32,
}

#[derive(Clone, Debug)]
struct MeshData {
    name: String,
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    normals: Option<Vec<Vec3>>,
    texcoords: Option<Vec<Vec2>>,
    material: Option<u32>,
}

#[derive(Clone, Debug)]
struct TextureData {
    name: String,
    png: Vec<u8>,
    wrap_s: Wrap,
    wrap_t: Wrap,
}

#[derive(Clone, Debug)]
struct NodeData {
    desc: NodeDesc,
    camera: Option<u32>,
    light: Option<u32>,
}

#[derive(Clone, Debug)]
struct CameraData {
    name: String,
    yfov: f32,
    aspect: Option<f32>,
}

#[derive(Clone, Debug)]
enum LightKind {
    Point,
    Spot { inner: f32, outer: f32 },
    Directional,
}

#[derive(Clone, Debug)]
struct LightData {
    name: String,
    kind: LightKind,
    color: [f32; 3],
    intensity: f32,
}

/// Collects meshes, materials, cameras and lights and writes them as glTF 2.0.
#[derive(Clone, Debug, Default)]
pub struct GltfBuilder {
    materials: Vec<MaterialDesc>,
    meshes: Vec<MeshData>,
    nodes: Vec<NodeData>,
    cameras: Vec<CameraData>,
    lights: Vec<LightData>,
    textures: Vec<TextureData>,
    index_width: IndexWidth,
}

impl GltfBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Chooses the index width of all meshes (default [`IndexWidth::Auto`]). Panics at write
    /// time if an index does not fit.
    pub fn index_width(&mut self, width: IndexWidth) -> &mut Self {
        self.index_width = width;
        self
    }

    /// Adds a material; returns its index.
    pub fn material(&mut self, m: MaterialDesc) -> u32 {
        if let Some(t) = m.base_color_texture {
            assert!(
                (t as usize) < self.textures.len(),
                "material '{}': no texture {t}",
                m.name
            );
        }
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Adds a mesh (one triangle-list primitive) without a node; returns the mesh index.
    /// An empty `indices` writes a non-indexed primitive (`positions` taken three at a time).
    pub fn add_mesh(
        &mut self,
        name: &str,
        positions: &[Vec3],
        indices: &[u32],
        normals: Option<&[Vec3]>,
        material: Option<u32>,
    ) -> u32 {
        if let Some(n) = normals {
            assert_eq!(n.len(), positions.len(), "mesh '{name}': one normal per position");
        }
        if let Some(m) = material {
            assert!((m as usize) < self.materials.len(), "mesh '{name}': no material {m}");
        }
        self.meshes.push(MeshData {
            name: name.to_string(),
            positions: positions.to_vec(),
            indices: indices.to_vec(),
            normals: normals.map(|n| n.to_vec()),
            texcoords: None,
            material,
        });
        (self.meshes.len() - 1) as u32
    }

    /// Gives mesh `mesh` texture coordinates (`TEXCOORD_0`, `FLOAT`), one per position; glTF's
    /// convention: (0, 0) is the top-left corner of the image.
    pub fn texcoords(&mut self, mesh: u32, uv: &[Vec2]) -> &mut Self {
        let m = &mut self.meshes[mesh as usize];
        assert_eq!(uv.len(), m.positions.len(), "mesh '{}': one uv per position", m.name);
        m.texcoords = Some(uv.to_vec());
        self
    }

    /// Adds a texture whose image is an embedded PNG of `width × height` sRGB-encoded 8-bit
    /// texels (`rows[y * width + x]`, row 0 at the top, i.e. at v = 0), with a sampler of the
    /// given wrap modes (bilinear filtering); returns the texture index for
    /// [`MaterialDesc::base_color_texture`].
    pub fn texture_png(
        &mut self,
        name: &str,
        width: u32,
        height: u32,
        srgb: &[[u8; 3]],
        wrap_s: Wrap,
        wrap_t: Wrap,
    ) -> u32 {
        assert_eq!(
            srgb.len() as u64,
            width as u64 * height as u64,
            "texture '{name}': width × height texels"
        );
        let bytes: Vec<u8> = srgb.iter().flatten().copied().collect();
        let mut png = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            &bytes,
            width,
            height,
            image::ExtendedColorType::Rgb8,
        )
        .expect("PNG encoding to memory succeeds");
        self.textures.push(TextureData {
            name: name.to_string(),
            png,
            wrap_s,
            wrap_t,
        });
        (self.textures.len() - 1) as u32
    }

    /// Adds a mesh and a root node of the same name with the identity transform; returns the
    /// mesh index.
    pub fn mesh(
        &mut self,
        name: &str,
        positions: &[Vec3],
        indices: &[u32],
        normals: Option<&[Vec3]>,
        material: Option<u32>,
    ) -> u32 {
        let mesh = self.add_mesh(name, positions, indices, normals, material);
        self.node(NodeDesc::new(name).with_mesh(mesh));
        mesh
    }

    /// Adds a node; returns its index. Nodes that are nobody's child are the scene's roots.
    pub fn node(&mut self, desc: NodeDesc) -> u32 {
        self.nodes.push(NodeData {
            desc,
            camera: None,
            light: None,
        });
        (self.nodes.len() - 1) as u32
    }

    /// Adds a perspective camera on a node at `eye` looking at `target` (the node's −Z points
    /// at `target`, +Y as close to `up` as possible); returns the node index.
    /// `aspect` (width / height) is written as `aspectRatio` when given.
    pub fn camera_look_at(
        &mut self,
        name: &str,
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        yfov_radians: f32,
        aspect: Option<f32>,
    ) -> u32 {
        let z = (eye - target).normalize();
        // An `up` parallel to the view direction leaves roll undefined: pick any perpendicular.
        let x = up
            .cross(z)
            .try_normalize()
            .unwrap_or_else(|| z.any_orthonormal_vector());
        let y = z.cross(x);
        let rotation = Quat::from_mat3(&Mat3::from_cols(x, y, z)).normalize();
        self.cameras.push(CameraData {
            name: name.to_string(),
            yfov: yfov_radians,
            aspect,
        });
        let camera = (self.cameras.len() - 1) as u32;
        let node = self.node(NodeDesc::new(name).with_translation(eye).with_rotation(rotation));
        self.nodes[node as usize].camera = Some(camera);
        node
    }

    /// Adds a point light (radiant intensity `color × intensity`); returns the node index.
    pub fn point_light(&mut self, name: &str, position: Vec3, color: [f32; 3], intensity: f32) -> u32 {
        self.light_node(name, position, Quat::IDENTITY, LightKind::Point, color, intensity)
    }

    /// Adds a spot light pointing along `direction`, cone angles in radians; returns the node index.
    pub fn spot_light(
        &mut self,
        name: &str,
        position: Vec3,
        direction: Vec3,
        color: [f32; 3],
        intensity: f32,
        inner_cone_angle: f32,
        outer_cone_angle: f32,
    ) -> u32 {
        let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, direction.normalize());
        let kind = LightKind::Spot {
            inner: inner_cone_angle,
            outer: outer_cone_angle,
        };
        self.light_node(name, position, rotation, kind, color, intensity)
    }

    /// Adds a directional light travelling along `direction` (irradiance `color × illuminance`).
    pub fn directional_light(&mut self, name: &str, direction: Vec3, color: [f32; 3], illuminance: f32) -> u32 {
        let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, direction.normalize());
        self.light_node(name, Vec3::ZERO, rotation, LightKind::Directional, color, illuminance)
    }

    fn light_node(
        &mut self,
        name: &str,
        position: Vec3,
        rotation: Quat,
        kind: LightKind,
        color: [f32; 3],
        intensity: f32,
    ) -> u32 {
        self.lights.push(LightData {
            name: name.to_string(),
            kind,
            color,
            intensity,
        });
        let light = (self.lights.len() - 1) as u32;
        let node = self.node(NodeDesc::new(name).with_translation(position).with_rotation(rotation));
        self.nodes[node as usize].light = Some(light);
        node
    }

    /// The glTF JSON with its single buffer embedded as a base64 data URI.
    pub fn to_json_string(&self) -> String {
        let (mut root, bin) = self.build();
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        );
        if !bin.is_empty() {
            root["buffers"][0]["uri"] = Value::String(uri);
        }
        let mut s = serde_json::to_string_pretty(&root).expect("glTF JSON serializes");
        s.push('\n');
        s
    }

    /// Writes a `.gltf` with embedded buffers.
    pub fn write_gltf(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.to_json_string())
    }

    /// The binary glTF (`.glb`) container: JSON chunk + BIN chunk.
    pub fn to_glb_bytes(&self) -> Vec<u8> {
        let (root, bin) = self.build();
        let mut json = serde_json::to_vec(&root).expect("glTF JSON serializes");
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = bin;
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        if !bin.is_empty() {
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
        }
        out
    }

    /// Writes a `.glb`.
    pub fn write_glb(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.to_glb_bytes())
    }

    /// Builds the JSON (buffer without `uri`) and the binary buffer.
    fn build(&self) -> (Value, Vec<u8>) {
        let mut bin: Vec<u8> = Vec::new();
        let mut views: Vec<Value> = Vec::new();
        let mut accessors: Vec<Value> = Vec::new();
        let mut push_view = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| -> usize {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            views.push(json!({
                "buffer": 0,
                "byteOffset": bin.len(),
                "byteLength": bytes.len(),
                "target": target,
            }));
            bin.extend_from_slice(bytes);
            views.len() - 1
        };
        const ARRAY_BUFFER: u32 = 34962;
        const ELEMENT_ARRAY_BUFFER: u32 = 34963;
        const FLOAT: u32 = 5126;

        let mut meshes = Vec::new();
        for m in &self.meshes {
            let mut attributes = Map::new();
            // A FLOAT accessor over `values` (`count` elements of `kind`), in its own view.
            let mut float_accessor = |values: Vec<f32>, count: usize, kind: &str| {
                let bytes: Vec<u8> = values.into_iter().flat_map(f32::to_le_bytes).collect();
                let view = push_view(&mut bin, &bytes, ARRAY_BUFFER);
                accessors.push(json!({ "bufferView": view, "componentType": FLOAT, "count": count, "type": kind }));
                accessors.len() - 1
            };
            let flat = |v: &[Vec3]| v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>();
            let position = float_accessor(flat(&m.positions), m.positions.len(), "VEC3");
            attributes.insert("POSITION".into(), json!(position));
            if let Some(normals) = &m.normals {
                attributes.insert(
                    "NORMAL".into(),
                    json!(float_accessor(flat(normals), normals.len(), "VEC3")),
                );
            }
            if let Some(uv) = &m.texcoords {
                let values = uv.iter().flat_map(|p| p.to_array()).collect();
                attributes.insert("TEXCOORD_0".into(), json!(float_accessor(values, uv.len(), "VEC2")));
            }
            // glTF requires min/max on POSITION accessors.
            let (lo, hi) = m.positions.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), p| (lo.min(*p), hi.max(*p)),
            );
            if !m.positions.is_empty() && lo.is_finite() && hi.is_finite() {
                accessors[position]["min"] = vec3_json(lo);
                accessors[position]["max"] = vec3_json(hi);
            }
            let mut prim = Map::new();
            prim.insert("attributes".into(), Value::Object(attributes));
            prim.insert("mode".into(), json!(4));
            if let Some(mat) = m.material {
                prim.insert("material".into(), json!(mat));
            }
            if !m.indices.is_empty() {
                let max = m.indices.iter().copied().max().unwrap_or(0);
                let width = match self.index_width {
                    IndexWidth::Auto if max <= u8::MAX as u32 => IndexWidth::U8,
                    IndexWidth::Auto if max <= u16::MAX as u32 => IndexWidth::U16,
                    IndexWidth::Auto => IndexWidth::U32,
                    w => w,
                };
                let (bytes, component): (Vec<u8>, u32) = match width {
                    IndexWidth::U8 => {
                        let v = m
                            .indices
                            .iter()
                            .map(|&i| u8::try_from(i).expect("index fits u8"))
                            .collect();
                        (v, 5121)
                    }
                    IndexWidth::U16 => {
                        let v = m
                            .indices
                            .iter()
                            .flat_map(|&i| u16::try_from(i).expect("index fits u16").to_le_bytes())
                            .collect();
                        (v, 5123)
                    }
                    _ => (m.indices.iter().flat_map(|i| i.to_le_bytes()).collect(), 5125),
                };
                let view = push_view(&mut bin, &bytes, ELEMENT_ARRAY_BUFFER);
                accessors.push(json!({
                    "bufferView": view,
                    "componentType": component,
                    "count": m.indices.len(),
                    "type": "SCALAR",
                }));
                prim.insert("indices".into(), json!(accessors.len() - 1));
            }
            meshes.push(json!({ "name": m.name, "primitives": [Value::Object(prim)] }));
        }
        let (mut images, mut samplers, mut textures) = (Vec::new(), Vec::new(), Vec::new());
        for (i, t) in self.textures.iter().enumerate() {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            views.push(json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": t.png.len() }));
            bin.extend_from_slice(&t.png);
            images.push(json!({ "name": t.name, "bufferView": views.len() - 1, "mimeType": "image/png" }));
            samplers.push(json!({
                "magFilter": 9729,
                "minFilter": 9729,
                "wrapS": t.wrap_s.gl_enum(),
                "wrapT": t.wrap_t.gl_enum(),
            }));
            textures.push(json!({ "name": t.name, "sampler": i, "source": i }));
        }
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }

        let mut used: Vec<&str> = Vec::new();
        let mut materials = Vec::new();
        for m in &self.materials {
            let mut o = Map::new();
            o.insert("name".into(), json!(m.name));
            let mut pbr = json!({
                "baseColorFactor": [num(m.base_color[0]), num(m.base_color[1]), num(m.base_color[2]), num(1.0)],
                "metallicFactor": num(0.0),
                "roughnessFactor": num(1.0),
            });
            if let Some(t) = m.base_color_texture {
                pbr["baseColorTexture"] = json!({ "index": t });
            }
            o.insert("pbrMetallicRoughness".into(), pbr);
            if m.emissive != [0.0; 3] {
                o.insert("emissiveFactor".into(), json!(m.emissive.map(num)));
            }
            if m.double_sided {
                o.insert("doubleSided".into(), json!(true));
            }
            let mut ext = Map::new();
            if m.emissive_strength != 1.0 {
                ext.insert(
                    "KHR_materials_emissive_strength".into(),
                    json!({ "emissiveStrength": num(m.emissive_strength) }),
                );
                used.push("KHR_materials_emissive_strength");
            }
            if m.transmission > 0.0 {
                ext.insert(
                    "KHR_materials_transmission".into(),
                    json!({ "transmissionFactor": num(m.transmission) }),
                );
                used.push("KHR_materials_transmission");
            }
            if m.transmission > 0.0 || m.ior != 1.5 {
                ext.insert("KHR_materials_ior".into(), json!({ "ior": num(m.ior) }));
                used.push("KHR_materials_ior");
            }
            if !ext.is_empty() {
                o.insert("extensions".into(), Value::Object(ext));
            }
            materials.push(Value::Object(o));
        }

        let cameras: Vec<Value> = self
            .cameras
            .iter()
            .map(|c| {
                let mut p = Map::new();
                p.insert("yfov".into(), num(c.yfov));
                p.insert("znear".into(), num(0.001));
                if let Some(a) = c.aspect {
                    p.insert("aspectRatio".into(), num(a));
                }
                json!({ "name": c.name, "type": "perspective", "perspective": Value::Object(p) })
            })
            .collect();

        let lights: Vec<Value> = self
            .lights
            .iter()
            .map(|l| {
                let mut o = Map::new();
                o.insert("name".into(), json!(l.name));
                o.insert("color".into(), json!(l.color.map(num)));
                o.insert("intensity".into(), num(l.intensity));
                match l.kind {
                    LightKind::Point => {
                        o.insert("type".into(), json!("point"));
                    }
                    LightKind::Directional => {
                        o.insert("type".into(), json!("directional"));
                    }
                    LightKind::Spot { inner, outer } => {
                        o.insert("type".into(), json!("spot"));
                        o.insert(
                            "spot".into(),
                            json!({ "innerConeAngle": num(inner), "outerConeAngle": num(outer) }),
                        );
                    }
                }
                Value::Object(o)
            })
            .collect();
        if !lights.is_empty() {
            used.push("KHR_lights_punctual");
        }

        let mut is_child = vec![false; self.nodes.len()];
        let mut nodes = Vec::new();
        for n in &self.nodes {
            let d = &n.desc;
            let mut o = Map::new();
            o.insert("name".into(), json!(d.name));
            if let Some(m) = d.mesh {
                assert!((m as usize) < self.meshes.len(), "node '{}': no mesh {m}", d.name);
                o.insert("mesh".into(), json!(m));
            }
            if let Some(c) = n.camera {
                o.insert("camera".into(), json!(c));
            }
            if let Some(l) = n.light {
                o.insert("extensions".into(), json!({ "KHR_lights_punctual": { "light": l } }));
            }
            if d.translation != Vec3::ZERO {
                o.insert("translation".into(), vec3_json(d.translation));
            }
            if d.rotation != Quat::IDENTITY {
                o.insert("rotation".into(), json!(d.rotation.to_array().map(num)));
            }
            if d.scale != Vec3::ONE {
                o.insert("scale".into(), vec3_json(d.scale));
            }
            if !d.children.is_empty() {
                for &c in &d.children {
                    assert!((c as usize) < self.nodes.len(), "node '{}': no child node {c}", d.name);
                    is_child[c as usize] = true;
                }
                o.insert("children".into(), json!(d.children));
            }
            nodes.push(Value::Object(o));
        }
        let roots: Vec<usize> = (0..self.nodes.len()).filter(|&i| !is_child[i]).collect();

        used.sort_unstable();
        used.dedup();
        let mut root = Map::new();
        root.insert(
            "asset".into(),
            json!({ "version": "2.0", "generator": "beamlight-scene gltf_writer" }),
        );
        root.insert("scene".into(), json!(0));
        root.insert("scenes".into(), json!([{ "name": "Scene", "nodes": roots }]));
        root.insert("nodes".into(), Value::Array(nodes));
        if !meshes.is_empty() {
            root.insert("meshes".into(), Value::Array(meshes));
            root.insert("accessors".into(), Value::Array(accessors));
        }
        if !views.is_empty() {
            root.insert("bufferViews".into(), Value::Array(views));
            root.insert("buffers".into(), json!([{ "byteLength": bin.len() }]));
        }
        if !textures.is_empty() {
            root.insert("images".into(), Value::Array(images));
            root.insert("samplers".into(), Value::Array(samplers));
            root.insert("textures".into(), Value::Array(textures));
        }
        if !materials.is_empty() {
            root.insert("materials".into(), Value::Array(materials));
        }
        if !cameras.is_empty() {
            root.insert("cameras".into(), Value::Array(cameras));
        }
        if !lights.is_empty() {
            root.insert(
                "extensions".into(),
                json!({ "KHR_lights_punctual": { "lights": lights } }),
            );
        }
        if !used.is_empty() {
            root.insert("extensionsUsed".into(), json!(used));
        }
        (Value::Object(root), bin)
    }
}

/// A JSON number holding the shortest decimal that reads back as the same `f32`.
fn num(x: f32) -> Value {
    assert!(x.is_finite(), "glTF numbers must be finite, got {x}");
    let shortest: f64 = x.to_string().parse().expect("f32 display parses");
    serde_json::Number::from_f64(shortest)
        .map(Value::Number)
        .expect("finite")
}

fn vec3_json(v: Vec3) -> Value {
    json!([num(v.x), num(v.y), num(v.z)])
}
