//! The glTF node hierarchy flattened: mesh instances, lights and cameras with their world
//! transforms.
use super::Src;
use super::names::node_label;
use crate::SceneError;
use glam::{Mat4, Quat, Vec3};
use gltf::json;

/// The nodes of the chosen scene, flattened with world transforms.
pub(super) struct Traversal {
    /// (node, mesh, world) in depth-first order.
    pub instances: Vec<(usize, usize, Mat4)>,
    /// (node, camera, world).
    pub cameras: Vec<(usize, usize, Mat4)>,
    /// (node, light, world).
    pub lights: Vec<(usize, usize, Mat4)>,
}

pub(super) fn local_matrix(src: &Src, root: &json::Root, i: usize) -> Result<Mat4, SceneError> {
    let n = &root.nodes[i];
    let m = if let Some(m) = n.matrix {
        Mat4::from_cols_array(&m)
    } else {
        let t = Vec3::from(n.translation.unwrap_or([0.0; 3]));
        let r = n.rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
        let s = Vec3::from(n.scale.unwrap_or([1.0; 3]));
        let q = Quat::from_array(r);
        if !(q.length() > 1e-6) || !q.is_finite() {
            return Err(src.err(format!(
                "{}: rotation {r:?} is not a unit quaternion",
                node_label(root, i)
            )));
        }
        Mat4::from_scale_rotation_translation(s, q.normalize(), t)
    };
    if !m.is_finite() {
        return Err(src.err(format!("{}: transform has non-finite entries", node_label(root, i))));
    }
    Ok(m)
}

pub(super) fn traverse(src: &Src, root: &json::Root, warnings: &mut Vec<String>) -> Result<Traversal, SceneError> {
    let roots: Vec<usize> = match root
        .scene
        .map(|s| s.value())
        .or(if root.scenes.is_empty() { None } else { Some(0) })
    {
        Some(s) => root.scenes[s].nodes.iter().map(|n| n.value()).collect(),
        None => {
            let mut is_child = vec![false; root.nodes.len()];
            for n in &root.nodes {
                for c in n.children.iter().flatten() {
                    is_child[c.value()] = true;
                }
            }
            if !root.nodes.is_empty() {
                warnings.push(format!(
                    "{}: no scene defined; using every node without a parent",
                    src.name()
                ));
            }
            (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut out = Traversal {
        instances: Vec::new(),
        cameras: Vec::new(),
        lights: Vec::new(),
    };
    // Explicit stack (no recursion depth limit); children pushed in reverse for pre-order.
    let mut stack: Vec<(usize, Mat4)> = roots.iter().rev().map(|&r| (r, Mat4::IDENTITY)).collect();
    while let Some((i, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[i], true) {
            return Err(src.err(format!(
                "{} is reached twice in the node hierarchy (a cycle, or more than one parent), which glTF forbids",
                node_label(root, i)
            )));
        }
        let world = parent * local_matrix(src, root, i)?;
        if !world.is_finite() {
            return Err(src.err(format!("{}: world transform overflows", node_label(root, i))));
        }
        let n = &root.nodes[i];
        if let Some(m) = n.mesh {
            out.instances.push((i, m.value(), world));
        }
        if let Some(c) = n.camera {
            out.cameras.push((i, c.value(), world));
        }
        if let Some(l) = n.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref()) {
            let count = root
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
                .map_or(0, |l| l.lights.len());
            if l.light.value() >= count {
                return Err(src.err(format!(
                    "{}: light {} does not exist",
                    node_label(root, i),
                    l.light.value()
                )));
            }
            out.lights.push((i, l.light.value(), world));
        }
        for c in n.children.iter().flatten().rev() {
            stack.push((c.value(), world));
        }
    }
    Ok(out)
}
