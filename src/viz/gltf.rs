//! A recorded run as binary glTF 2.0 ([`glb_bytes`], [`write_glb`]).
//!
//! The document has one scene whose single root node, [`ROOT_NODE`], turns gelenk's z-up world
//! into glTF's y-up one (a rotation of −90° about x: world (x, y, z) is glTF (x, z, −y)). Under it:
//! - one node per moving body that carries colliders, named `multibody/body` as in
//!   [`crate::run::FramedBody::name`], whose mesh has one primitive per collider (its shape in the
//!   body frame, coloured by multibody, every other body darker);
//! - one node per static collider (ground, terrain, walls; the fixed base of a robot), named as
//!   the collider, its mesh in world coordinates; a half-space is a square of side
//!   [`GROUND_SIZE_FACTOR`] times the bodies' travel (at least [`GROUND_MIN_SIZE`]), centred
//!   under them;
//! - one animation, [`ANIMATION`], with a translation and a rotation channel per body node,
//!   keyed at the recorded instants (linear interpolation; quaternions kept on one hemisphere
//!   from key to key so that interpolation takes the short way).
//!
//! Numbers are single precision, as glTF stores them: positions to about 1e-7 of their size.

use super::mesh::{self, TriangleMesh};
use super::{check_frames, focus, OutputFile, VizError};
use crate::collision::Attachment;
use crate::math::Vec3;
use crate::run::Recording;
use crate::world::World;
use gltf::json;
use json::validation::{Checked::Valid, USize64};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

/// Name of the root node that turns the z-up world into glTF's y-up.
pub const ROOT_NODE: &str = "world (z up)";
/// Name of the animation.
pub const ANIMATION: &str = "run";
/// The ground square's side, in units of the bodies' travel (the diagonal of their origins'
/// bounding box over the run).
pub const GROUND_SIZE_FACTOR: f64 = 3.0;
/// Smallest side of the ground square (m).
pub const GROUND_MIN_SIZE: f64 = 20.0;

/// The rotation of [`ROOT_NODE`] (x, y, z, w): −90° about x.
const Z_UP_TO_Y_UP: [f32; 4] = [-std::f32::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2];

/// Colours of the multibodies (linear RGB), by index, repeating.
const PALETTE: [[f32; 3]; 8] = [
    [0.80, 0.30, 0.10],
    [0.10, 0.35, 0.75],
    [0.85, 0.65, 0.10],
    [0.15, 0.55, 0.25],
    [0.55, 0.20, 0.60],
    [0.10, 0.55, 0.60],
    [0.75, 0.15, 0.25],
    [0.45, 0.45, 0.50],
];
/// Factor on the (linear) colour of every other body of a multibody, in the order of the
/// recording's bodies.
const DARKER_SHADE: f32 = 0.35;
const STATIC_COLOUR: [f32; 3] = [0.42, 0.44, 0.40];

/// The run as binary glTF (see the module's description). The recording must hold frames
/// ([`crate::run::RunOptions::record_frames`]) recorded from `world`.
pub fn glb_bytes(world: &World, recording: &Recording) -> Result<Vec<u8>, VizError> {
    check_frames(recording)?;
    let mut doc = Document::new();
    let mut children = Vec::new();

    // Static geometry, in world coordinates.
    let bounds = focus(recording);
    let centre = (bounds.min + bounds.max) * 0.5;
    let half_size = 0.5 * (GROUND_SIZE_FACTOR * (bounds.max - bounds.min).norm()).max(GROUND_MIN_SIZE);
    let ground = doc.material("static", STATIC_COLOUR, true);
    for c in world.collision().colliders().iter().filter(|c| c.attachment().is_static()) {
        let (shape, pose) = c.parry_local();
        let shape_mesh = match mesh::half_space(shape, pose) {
            Some((point, normal)) => Some(mesh::plane_square(&point, &normal, &centre, half_size)),
            None => mesh::shape_mesh(shape, pose),
        };
        if let Some(m) = shape_mesh {
            let mesh = doc.mesh(c.name(), &[m], ground);
            children.push(doc.root.push(json::Node {
                mesh: Some(mesh),
                name: Some(c.name().to_string()),
                ..Default::default()
            }));
        }
    }

    // Moving bodies: their colliders in the body frame.
    let mut shapes: BTreeMap<(usize, usize), Vec<TriangleMesh>> = BTreeMap::new();
    for c in world.collision().colliders() {
        if let Attachment::Body { multibody, body } = c.attachment() {
            let (shape, pose) = c.parry_local();
            if let Some(m) = mesh::shape_mesh(shape, pose) {
                shapes.entry((multibody, body)).or_default().push(m);
            }
        }
    }
    let mut materials = BTreeMap::new();
    let first = &recording.frames[0];
    let mut body_nodes = Vec::with_capacity(recording.bodies.len());
    let mut rank = BTreeMap::new();
    for (k, body) in recording.bodies.iter().enumerate() {
        // A multibody's bodies alternate between two shades of its colour: the joints show.
        let next = rank.entry(body.multibody).or_insert(0usize);
        let parity = *next % 2;
        *next += 1;
        let shade = if parity == 0 { 1.0 } else { DARKER_SHADE };
        let colour = PALETTE[body.multibody % PALETTE.len()].map(|c| c * shade);
        let material = *materials.entry((body.multibody, parity)).or_insert_with(|| {
            doc.material(&format!("{} {parity}", world.multibody_name(body.multibody)), colour, false)
        });
        let mesh = shapes
            .get(&(body.multibody, body.body))
            .filter(|m| !m.is_empty())
            .map(|m| doc.mesh(&body.name, m, material));
        let pose = &first.poses[k];
        let node = doc.root.push(json::Node {
            mesh,
            name: Some(body.name.clone()),
            translation: Some(f32x3(&pose.translation)),
            rotation: Some(json::scene::UnitQuaternion(pose.rotation.map(|x| x as f32))),
            ..Default::default()
        });
        children.push(node);
        body_nodes.push(node);
    }

    doc.animation(recording, &body_nodes);
    let root_node = doc.root.push(json::Node {
        children: Some(children),
        name: Some(ROOT_NODE.to_string()),
        rotation: Some(json::scene::UnitQuaternion(Z_UP_TO_Y_UP)),
        ..Default::default()
    });
    let scene = doc.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(recording.scene.clone()),
        nodes: vec![root_node],
    });
    doc.root.scene = Some(scene);
    doc.finish()
}

/// Writes [`glb_bytes`] to `path` (which must end in `.glb`), whole or not at all.
pub fn write_glb(world: &World, recording: &Recording, path: &Path) -> Result<(), VizError> {
    let out = OutputFile::create(path, "glb")?;
    out.commit(&glb_bytes(world, recording)?)
}

fn f32x3(v: &Vec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The JSON document and its binary buffer, as they grow.
struct Document {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
}

impl Document {
    fn new() -> Self {
        let mut root = json::Root {
            asset: json::Asset {
                generator: Some(format!("gelenk {}", env!("CARGO_PKG_VERSION"))),
                ..Default::default()
            },
            ..Default::default()
        };
        let buffer = root.push(json::Buffer {
            byte_length: USize64(0),
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            uri: None,
        });
        Self { root, bin: Vec::new(), buffer }
    }

    /// A buffer view of `bytes`, starting on a 4-byte boundary.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: target.map(Valid),
        })
    }

    /// An accessor of `values` (f32, `components` per element) in a view of its own, with the
    /// per-component minimum and maximum when `bounds`.
    fn floats(
        &mut self,
        values: &[f32],
        type_: json::accessor::Type,
        target: Option<json::buffer::Target>,
        bounds: bool,
    ) -> json::Index<json::Accessor> {
        let components = type_.multiplicity();
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        let (min, max) = if bounds {
            let mut lo = vec![f32::INFINITY; components];
            let mut hi = vec![f32::NEG_INFINITY; components];
            for element in values.chunks_exact(components) {
                for (i, v) in element.iter().enumerate() {
                    lo[i] = lo[i].min(*v);
                    hi[i] = hi[i].max(*v);
                }
            }
            (Some(json::Value::from(lo)), Some(json::Value::from(hi)))
        } else {
            (None, None)
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(values.len() / components),
            component_type: Valid(json::accessor::GenericComponentType(json::accessor::ComponentType::F32)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// An index accessor (u16 when the vertices allow, else u32).
    fn indices(&mut self, triangles: &[[u32; 3]], vertices: usize) -> json::Index<json::Accessor> {
        let flat = triangles.iter().flatten();
        let (bytes, component): (Vec<u8>, _) = if vertices <= u16::MAX as usize {
            (flat.flat_map(|&i| (i as u16).to_le_bytes()).collect(), json::accessor::ComponentType::U16)
        } else {
            (flat.flat_map(|&i| i.to_le_bytes()).collect(), json::accessor::ComponentType::U32)
        };
        let view = self.view(&bytes, Some(json::buffer::Target::ElementArrayBuffer));
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(triangles.len() * 3),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(json::accessor::Type::Scalar),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    fn material(&mut self, name: &str, rgb: [f32; 3], double_sided: bool) -> json::Index<json::Material> {
        self.root.push(json::Material {
            name: Some(name.to_string()),
            double_sided,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([rgb[0], rgb[1], rgb[2], 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.8),
                ..Default::default()
            },
            ..Default::default()
        })
    }

    /// A mesh with one primitive per triangle mesh, all in `material`.
    fn mesh(
        &mut self,
        name: &str,
        meshes: &[TriangleMesh],
        material: json::Index<json::Material>,
    ) -> json::Index<json::Mesh> {
        use json::accessor::Type;
        use json::buffer::Target::ArrayBuffer;
        let mut primitives = Vec::with_capacity(meshes.len());
        for m in meshes {
            let mut attributes = BTreeMap::new();
            let positions: Vec<f32> = m.positions.iter().flatten().copied().collect();
            let positions = self.floats(&positions, Type::Vec3, Some(ArrayBuffer), true);
            attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
            if let Some(normals) = &m.normals {
                let normals: Vec<f32> = normals.iter().flatten().copied().collect();
                let normals = self.floats(&normals, Type::Vec3, Some(ArrayBuffer), false);
                attributes.insert(Valid(json::mesh::Semantic::Normals), normals);
            }
            let indices = self.indices(&m.triangles, m.positions.len());
            primitives.push(json::mesh::Primitive {
                attributes,
                extensions: Default::default(),
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            });
        }
        self.root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: Some(name.to_string()),
            primitives,
            weights: None,
        })
    }

    /// The animation: a translation and a rotation channel per body node. Instants that single
    /// precision cannot tell from the previous one are left out (keys must increase strictly).
    fn animation(&mut self, recording: &Recording, nodes: &[json::Index<json::Node>]) {
        use json::accessor::Type;
        let mut keys = Vec::with_capacity(recording.rows.len());
        let mut times: Vec<f32> = Vec::with_capacity(recording.rows.len());
        for (k, row) in recording.rows.iter().enumerate() {
            let t = row.time as f32;
            if times.last().is_none_or(|last| t > *last) {
                times.push(t);
                keys.push(k);
            }
        }
        let input = self.floats(&times, Type::Scalar, None, true);
        let mut channels = Vec::with_capacity(2 * nodes.len());
        let mut samplers = Vec::with_capacity(2 * nodes.len());
        for (b, node) in nodes.iter().enumerate() {
            let mut translations = Vec::with_capacity(3 * keys.len());
            let mut rotations = Vec::with_capacity(4 * keys.len());
            let mut previous = [0.0f64, 0.0, 0.0, 1.0];
            for &k in &keys {
                let pose = &recording.frames[k].poses[b];
                translations.extend(f32x3(&pose.translation));
                let mut q = pose.rotation;
                if q.iter().zip(&previous).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                    q = q.map(|x| -x);
                }
                previous = q;
                rotations.extend(q.map(|x| x as f32));
            }
            for (values, type_, path) in [
                (translations, Type::Vec3, json::animation::Property::Translation),
                (rotations, Type::Vec4, json::animation::Property::Rotation),
            ] {
                let output = self.floats(&values, type_, None, false);
                let sampler = json::Index::push(
                    &mut samplers,
                    json::animation::Sampler {
                        extensions: Default::default(),
                        extras: Default::default(),
                        input,
                        interpolation: Valid(json::animation::Interpolation::Linear),
                        output,
                    },
                );
                channels.push(json::animation::Channel {
                    sampler,
                    target: json::animation::Target {
                        extensions: Default::default(),
                        extras: Default::default(),
                        node: *node,
                        path: Valid(path),
                    },
                    extensions: Default::default(),
                    extras: Default::default(),
                });
            }
        }
        if !channels.is_empty() {
            self.root.push(json::Animation {
                extensions: Default::default(),
                extras: Default::default(),
                channels,
                name: Some(ANIMATION.to_string()),
                samplers,
            });
        }
    }

    fn finish(mut self) -> Result<Vec<u8>, VizError> {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.root.buffers[self.buffer.value()].byte_length = USize64::from(self.bin.len());
        let json = self.root.to_vec().map_err(|e| VizError::Encode(e.to_string()))?;
        let length = 12 + 8 + json.len().div_ceil(4) * 4 + 8 + self.bin.len();
        if length > u32::MAX as usize {
            return Err(VizError::Encode(format!(
                "{length} bytes is more than a binary glTF file holds (4 GiB): record fewer frames"
            )));
        }
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: length as u32 },
            json: Cow::Owned(json),
            bin: Some(Cow::Owned(self.bin)),
        };
        glb.to_vec().map_err(|e| VizError::Encode(e.to_string()))
    }
}
