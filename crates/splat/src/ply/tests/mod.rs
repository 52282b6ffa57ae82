//! Unit tests for PLY parsing, writing and the activation conversions; `errors.rs`: every
//! malformed input ends in an error that names what is wrong, never a panic.

use super::header::Format;
use super::write::{encode, property_names, vertex_values};
use super::*;
use std::path::Path;

mod errors;

/// Deterministic, mutually distinct values, so a swapped property shows up.
fn sample(n: usize, rest: usize) -> PlyGaussians {
    let v = |i: usize, k: usize| ((i * 31 + k * 7) % 97) as f32 * 0.125 - 5.0;
    let v3 = |i, k| [v(i, k), v(i, k + 1), v(i, k + 2)];
    PlyGaussians {
        means: (0..n).map(|i| v3(i, 0)).collect(),
        f_dc: (0..n).map(|i| v3(i, 3)).collect(),
        f_rest: (0..n)
            .map(|i| (0..rest).map(|k| v(i, 100 + k)).collect())
            .collect(),
        opacity_logit: (0..n).map(|i| v(i, 6)).collect(),
        log_scales: (0..n).map(|i| v3(i, 7)).collect(),
        rotations: (0..n)
            .map(|i| [v(i, 10), v(i, 11), v(i, 12), v(i, 13)])
            .collect(),
    }
}

/// A header with the given format and `(element, count, property lines)`.
fn header(format: &str, elements: &[(&str, usize, Vec<String>)]) -> Vec<u8> {
    let mut h = format!("ply\nformat {format} 1.0\n");
    for (name, count, props) in elements {
        h.push_str(&format!("element {name} {count}\n"));
        for p in props {
            h.push_str(&format!("property {p}\n"));
        }
    }
    h.push_str("end_header\n");
    h.into_bytes()
}

/// The standard property lines (`float NAME`) for `rest` f_rest coefficients.
fn float_props(rest: usize) -> Vec<String> {
    property_names(rest)
        .iter()
        .map(|n| format!("float {n}"))
        .collect()
}

/// Value Gaussian `i` of `g` has for property `name`; 1.0 for extra names.
fn value_of(g: &PlyGaussians, i: usize, name: &str) -> f64 {
    let names = property_names(g.f_rest.first().map_or(0, Vec::len));
    names
        .iter()
        .zip(vertex_values(g, i))
        .find(|(n, _)| *n == name)
        .map_or(1.0, |(_, v)| v as f64)
}

/// Binary record of Gaussian `i` for `(type, name)` properties.
fn binary_record(g: &PlyGaussians, i: usize, props: &[(&str, &str)], big: bool) -> Vec<u8> {
    let mut out = Vec::new();
    for (ty, name) in props {
        let v = value_of(g, i, name);
        macro_rules! put {
            ($t:ty) => {{
                let x = v as $t;
                out.extend_from_slice(&if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                })
            }};
        }
        match *ty {
            "float" | "float32" => put!(f32),
            "double" | "float64" => put!(f64),
            "char" | "int8" => put!(i8),
            "uchar" | "uint8" => put!(u8),
            "short" | "int16" => put!(i16),
            "ushort" | "uint16" => put!(u16),
            "int" | "int32" => put!(i32),
            "uint" | "uint32" => put!(u32),
            other => panic!("test helper: unknown type {other}"),
        }
    }
    out
}

fn typed(props: &[(&str, &str)]) -> Vec<String> {
    props.iter().map(|(t, n)| format!("{t} {n}")).collect()
}

fn assert_close(a: &[f32], b: &[f32], tol: f32) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tol * (1.0 + y.abs()),
            "index {i}: {x} vs {y}"
        );
    }
}

/// Guards ascii encoding/decoding drift: every value must survive exactly.
#[test]
fn ascii_round_trip() {
    let g = sample(5, 3);
    assert_eq!(parse_ply(&encode(&g, Format::Ascii)).unwrap(), g);
}

/// Guards little-endian decoding (byte order, stride, f_rest placement).
#[test]
fn binary_le_round_trip() {
    let g = sample(7, 45);
    assert_eq!(parse_ply(&to_ply_bytes(&g)).unwrap(), g);
}

/// Guards big-endian decoding (a little-endian read would scramble values).
#[test]
fn binary_be_round_trip() {
    let g = sample(4, 0);
    assert_eq!(parse_ply(&encode(&g, Format::BinaryBigEndian)).unwrap(), g);
}

/// Guards the file path: write_ply/read_ply agree and leave no temp file.
#[test]
fn write_ply_read_ply_file_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.ply");
    let g = sample(3, 9);
    write_ply(&path, &g).unwrap();
    write_ply(&path, &g).unwrap(); // overwriting an existing file works
    assert_eq!(read_ply(&path).unwrap(), g);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// Guards against misreading data when other elements with list properties
/// (faces) and extra vertex properties of other types are present.
#[test]
fn extra_properties_and_face_element_skipped_binary() {
    let g = sample(3, 2);
    let mut vprops: Vec<(&str, &str)> = vec![("uchar", "red"), ("double", "extra_d")];
    let names = property_names(2);
    vprops.extend(names.iter().map(|n| ("float", n.as_str())));
    vprops.push(("short", "tail"));
    let face = vec![
        "list uchar int vertex_indices".to_owned(),
        "float area".into(),
    ];
    let mut bytes = header(
        "binary_little_endian",
        &[
            ("face", 2, face.clone()),
            ("vertex", 3, typed(&vprops)),
            ("edge", 5, face),
        ],
    );
    bytes.extend(std::iter::once(&3u8).chain(&[0u8; 12]).chain(&[0u8; 4])); // 3 indices + area
    bytes.extend(std::iter::once(&0u8).chain(&[0u8; 4])); // empty list + area
    for i in 0..3 {
        bytes.extend(binary_record(&g, i, &vprops, false));
    }
    bytes.extend([7u8; 3]); // a truncated trailing element is never read
    assert_eq!(parse_ply(&bytes).unwrap(), g);
}

/// Guards ascii skipping of elements before the vertex element.
#[test]
fn face_element_skipped_ascii() {
    let g = sample(2, 0);
    let text = String::from_utf8(encode(&g, Format::Ascii)).unwrap();
    let text = text.replacen(
        "element vertex",
        "element face 2\nproperty list uchar int vertex_indices\nelement vertex",
        1,
    );
    let text = text.replacen("end_header\n", "end_header\n3 0 1 2\n\n4 0 1 2 3\n", 1);
    assert_eq!(parse_ply(text.as_bytes()).unwrap(), g);
}

/// Guards against assuming the INRIA property order.
#[test]
fn property_order_shuffled() {
    let g = sample(4, 12);
    let names = property_names(12);
    let mut order: Vec<&str> = names.iter().map(String::as_str).collect();
    order.reverse();
    order.swap(0, 7);
    let props: Vec<(&str, &str)> = order.iter().map(|n| ("float", *n)).collect();
    for (format, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
        let mut bytes = header(format, &[("vertex", 4, typed(&props))]);
        for i in 0..4 {
            bytes.extend(binary_record(&g, i, &props, big));
        }
        assert_eq!(parse_ply(&bytes).unwrap(), g, "{format}");
    }
}

/// Guards the integer and double type aliases and their sizes.
#[test]
fn all_scalar_types_decode() {
    let names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity"];
    let more = [
        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ];
    let types = [
        "float32", "float64", "int16", "uint8", "int8", "uint16", "int32",
    ];
    let more_types = ["uint32", "char", "uchar", "short", "ushort", "int", "uint"];
    let props: Vec<(&str, &str)> = types
        .iter()
        .chain(&more_types)
        .zip(names.iter().chain(&more))
        .map(|(t, n)| (*t, *n))
        .collect();
    let mut g = sample(1, 0);
    g.means[0] = [1.5, -2.25, -3.0];
    g.f_dc[0] = [200.0, -100.0, 60000.0];
    g.opacity_logit[0] = -70000.0;
    g.log_scales[0] = [4e9, -5.0, 250.0];
    g.rotations[0] = [-300.0, 65535.0, 7.0, 4e9];
    let mut bytes = header("binary_big_endian", &[("vertex", 1, typed(&props))]);
    bytes.extend(binary_record(&g, 0, &props, true));
    assert_eq!(parse_ply(&bytes).unwrap(), g);
}

/// Guards that an empty scene is valid rather than an error.
#[test]
fn zero_vertices_allowed() {
    let g = parse_ply(&to_ply_bytes(&PlyGaussians::default())).unwrap();
    assert!(g.is_empty() && g.f_rest.is_empty());
    assert_eq!(g.to_render_params(), RenderParams::default());
}

/// Guards f_rest ordering by number: f_rest_10 follows f_rest_9.
#[test]
fn f_rest_ordering_with_ten_plus_coefficients() {
    let mut g = sample(2, 12);
    g.f_rest = vec![(0..12).map(|k| k as f32).collect(); 2];
    let mut names = property_names(12);
    names.sort(); // lexicographic: f_rest_0, f_rest_1, f_rest_10, f_rest_11, f_rest_2...
    let props: Vec<(&str, &str)> = names.iter().map(|n| ("float", n.as_str())).collect();
    let mut bytes = header("binary_little_endian", &[("vertex", 2, typed(&props))]);
    for i in 0..2 {
        bytes.extend(binary_record(&g, i, &props, false));
    }
    assert_eq!(parse_ply(&bytes).unwrap().f_rest, g.f_rest);
}

/// Guards the activations: colour clamp, stable sigmoid, exp scale,
/// quaternion normalisation and the zero quaternion staying zero.
#[test]
fn activation_values() {
    let g = PlyGaussians {
        means: vec![[1.0, 2.0, 3.0]; 3],
        f_dc: vec![[-10.0, 0.0, 1.0]; 3],
        f_rest: vec![vec![]; 3],
        opacity_logit: vec![0.0, 1000.0, -1000.0],
        log_scales: vec![[0.0, 2f32.ln(), 1000.0]; 3],
        rotations: vec![[2.0, 0.0, 0.0, 0.0], [1.0; 4], [0.0; 4]],
    };
    let p = g.to_render_params();
    assert_eq!(p.means, [1.0, 2.0, 3.0].repeat(3));
    assert_close(&p.colors[..3], &[0.0, 0.5, 0.5 + SH_C0 as f32], 1e-6);
    assert_eq!(p.opacities, vec![0.5, 1.0, 0.0]);
    assert_close(&p.scales[..2], &[1.0, 2.0], 1e-6);
    assert_eq!(p.scales[2], f32::MAX);
    assert_eq!(&p.quats[..4], &[1.0, 0.0, 0.0, 0.0]);
    assert_close(&p.quats[4..8], &[0.5; 4], 1e-7);
    assert_eq!(&p.quats[8..], &[0.0; 4]);
    assert!(p.quats.iter().chain(&p.opacities).all(|v| v.is_finite()));
}

/// Guards from_render_params as the inverse of to_render_params, through a
/// file, and its rejection of values that have no stored form.
#[test]
fn render_params_round_trip() {
    let mut g = sample(6, 0);
    g.f_dc[0] = [-10.0, 0.0, 0.0]; // clamped colour: must stay clamped
    let p = g.to_render_params();
    let back = PlyGaussians::from_render_params(&p).unwrap();
    let q = parse_ply(&to_ply_bytes(&back)).unwrap().to_render_params();
    assert_close(&q.means, &p.means, 1e-6);
    assert_close(&q.quats, &p.quats, 1e-6);
    assert_close(&q.scales, &p.scales, 1e-5);
    assert_close(&q.opacities, &p.opacities, 1e-5);
    assert_close(&q.colors, &p.colors, 1e-5);
    let mut bad = p.clone();
    bad.scales[4] = 0.0;
    assert!(matches!(
        PlyGaussians::from_render_params(&bad),
        Err(PlyError::InvalidRenderParam { index: 1, .. })
    ));
    bad = p.clone();
    bad.quats.pop();
    assert!(matches!(
        PlyGaussians::from_render_params(&bad),
        Err(PlyError::Inconsistent(_))
    ));
    bad = p;
    bad.opacities = vec![0.0, 1.0, 0.5, 0.5, 0.5, 0.5];
    let o = PlyGaussians::from_render_params(&bad)
        .unwrap()
        .opacity_logit;
    assert!(o[0].is_finite() && o[1].is_finite() && o[0] < -13.0 && o[1] > 13.0);
}
