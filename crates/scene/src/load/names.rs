//! Names for messages: how a node, mesh or material of the glTF is quoted, and lists of
//! valid choices.
use gltf::json;

/// "`label`: 'a', 'b'" (sorted, without repeats), or `none` when there are no names: the list
/// of valid choices an error message offers.
pub(super) fn name_list<'a>(names: impl Iterator<Item = &'a str>, label: &str, none: &str) -> String {
    let mut names: Vec<String> = names.map(|n| format!("'{n}'")).collect();
    names.sort();
    names.dedup();
    if names.is_empty() {
        none.to_string()
    } else {
        format!("{label}: {}", names.join(", "))
    }
}

pub(super) fn quoted(name: Option<&String>, kind: &str, i: usize) -> String {
    match name {
        Some(n) => format!("{kind} '{n}'"),
        None => format!("{kind} #{i}"),
    }
}

pub(super) fn mesh_name(m: &json::Mesh, i: usize) -> String {
    m.name.clone().unwrap_or_else(|| format!("mesh #{i}"))
}

pub(super) fn node_label(root: &json::Root, i: usize) -> String {
    quoted(root.nodes[i].name.as_ref(), "node", i)
}

pub(super) fn mesh_label(root: &json::Root, i: usize) -> String {
    quoted(root.meshes[i].name.as_ref(), "mesh", i)
}

pub(super) fn material_label(root: &json::Root, i: usize) -> String {
    quoted(root.materials[i].name.as_ref(), "material", i)
}
