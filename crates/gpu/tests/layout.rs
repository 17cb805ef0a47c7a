//! The Rust side of every struct crossing the CPU–GPU boundary matches its WGSL twin: size,
//! alignment, and each member's name and offset, as naga lays the WGSL out.
use beamlight_gpu::{layout::*, shaders};
use std::collections::HashMap;

/// A WGSL struct as naga lays it out: size, alignment, and (member, offset) in order.
type StructLayout = (u32, u32, Vec<(String, u32)>);

struct Wgsl {
    structs: HashMap<String, StructLayout>,
}

fn parse(kernel: &str) -> Wgsl {
    let source = shaders::compose(kernel).unwrap();
    let module = naga::front::wgsl::parse_str(&source).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let mut structs = HashMap::new();
    for (handle, ty) in module.types.iter() {
        if let (Some(name), naga::TypeInner::Struct { members, .. }) = (&ty.name, &ty.inner) {
            let l = &layouter[handle];
            let members = members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect();
            structs.insert(name.clone(), (l.size, l.alignment.round_up(1), members));
        }
    }
    Wgsl { structs }
}

macro_rules! check {
    ($wgsl:expr, $ty:ident, [$($field:ident),* $(,)?]) => {{
        let (size, align, members) = $wgsl
            .structs
            .get(stringify!($ty))
            .unwrap_or_else(|| panic!("no WGSL struct {}", stringify!($ty)));
        assert_eq!(*size as usize, size_of::<$ty>(), "size of {}", stringify!($ty));
        // WGSL may align a struct more strictly than Rust (vec3 → 16); arrays of it must then
        // still have the same stride, which the size check above covers. Rust must never be
        // more strictly aligned than WGSL.
        assert!(align_of::<$ty>() <= *align as usize, "alignment of {}", stringify!($ty));
        assert_eq!(size % align, 0);
        let rust: Vec<(String, u32)> = vec![$((stringify!($field).to_string(), std::mem::offset_of!($ty, $field) as u32)),*];
        assert_eq!(members, &rust, "members of {}", stringify!($ty));
    }};
}

#[test]
fn scene_structs_match() {
    let w = parse("trace_rays.wgsl");
    check!(w, BvhNode, [lo, count, hi, first]);
    check!(w, Triangle, [p0, id, p1, _pad1, p2, _pad2]);
    check!(
        w,
        TriangleInfo,
        [leaf_slot, flags, inside, outside, patch_start, patch_count]
    );
    check!(w, PatchEdge, [a, sides, b, _pad1]);
    check!(
        w,
        Medium,
        [
            sigma_s,
            g,
            sigma_a,
            grid_offset,
            grid_lo,
            majorant_offset,
            grid_hi,
            _pad,
            grid_res,
            _pad2,
            majorant_res,
            _pad3
        ]
    );
    check!(
        w,
        SceneInfo,
        [node_count, has_null_interfaces, medium_count, triangle_split]
    );
    check!(w, Ray, [o, tmax, d, any_hit]);
    check!(w, Hit, [t, tri, b1, b2]);
    check!(w, RayBatch, [count, row, _pad0, _pad1]);
}

#[test]
fn gather_structs_match() {
    use beamlight_trace::{
        camera_paths::{MediaSegment, ShadingPoint},
        light_paths::{LightSegment, SurfaceVertex},
    };
    let w = parse("vpl_surface.wgsl");
    check!(w, Bsdf, [diffuse, exponent, specular, kind]);
    check!(
        w,
        GatherParams,
        [
            pair_seed,
            pass_index,
            records,
            lights,
            row,
            clamp,
            scale,
            radius2,
            directions,
            pdf_vertices,
            uniform_share,
            angular_pdf,
            record_offset,
            light_samples,
            vsl_tree_nodes,
            vbl_tree_nodes,
            poison,
            media_drawing,
            first_light,
            light_chunk
        ]
    );
    check!(
        w,
        ShadingPoint,
        [pos, material, normal, tri, wo, pixel, throughput, medium, uv, _pad2]
    );
    check!(w, MediaSegment, [origin, length, dir, medium, throughput, pixel]);
    check!(w, SurfaceVertex, [pos, material, normal, tri, wi, u, power, v]);
    check!(w, LightSegment, [origin, length, dir, medium, power, flags]);
    let w = parse("vbl_media.wgsl");
    use beamlight_trace::light_tree::LightTreeNode;
    check!(
        w,
        LightTreeNode,
        [
            lo,
            weight,
            hi,
            child,
            sigma_t,
            g,
            lobe_share,
            lobe_cos,
            lobe_axis,
            lobe_exponent,
            normal,
            normal_cos,
            lobe_peak,
            lobe_base,
            _pad
        ]
    );
    let w = parse("vsl_media.wgsl");
    check!(w, Plane, [point, _pad0, normal, _pad1]);
    check!(w, Walls, [planes, count, _pad0, _pad1, _pad2]);
}
