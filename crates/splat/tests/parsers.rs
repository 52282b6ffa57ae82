//! Property tests of the splat crate's parsers: thousands of randomly damaged PLY files
//! (binary and ascii) and camera JSON files; each gives an error or a valid result, never a
//! panic, and whatever parses also converts to render parameters without a panic.

#[path = "../../../tests/support/mutate.rs"]
mod mutate;

use envision4d_splat::camera_json::parse_camera_json;
use envision4d_splat::ply::{parse_ply, to_ply_bytes, PlyGaussians};
use proptest::prelude::*;

/// Two Gaussians with degree-1 SH, as binary little-endian PLY.
fn binary_ply() -> Vec<u8> {
    let g = PlyGaussians {
        means: vec![[0.0, 1.0, 2.0], [-1.5, 0.25, 8.0]],
        f_dc: vec![[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]],
        f_rest: vec![(0..9).map(|i| i as f32 * 0.1).collect(); 2],
        opacity_logit: vec![0.5, -2.0],
        log_scales: vec![[-1.0, -2.0, -3.0], [0.0, 0.5, -0.5]],
        rotations: vec![[1.0, 0.0, 0.0, 0.0], [0.7, 0.1, 0.0, 0.7]],
    };
    to_ply_bytes(&g)
}

/// The same kind of scene as ascii PLY, with a face element before the vertices.
const ASCII_PLY: &str = "ply
format ascii 1.0
comment written by hand
element face 1
property list uchar int vertex_indices
element vertex 2
property float x
property float y
property float z
property float f_dc_0
property float f_dc_1
property float f_dc_2
property float opacity
property float scale_0
property float scale_1
property float scale_2
property float rot_0
property float rot_1
property float rot_2
property float rot_3
end_header
3 0 1 1
0 1 2 0.1 0.2 0.3 0.5 -1 -2 -3 1 0 0 0
-1.5 0.25 8 0.4 0.5 0.6 -2 0 0.5 -0.5 0.7 0.1 0 0.7
";

const CAMERA: &str = r#"{
    "width": 640, "height": 480,
    "fx": 500.0, "fy": 510.0, "cx": 320.0, "cy": 240.5,
    "world_to_camera": [[1, 0, 0, 0.5], [0, 1, 0, -1], [0, 0, 1, 3], [0, 0, 0, 1]]
}"#;

/// Parses, and uses what parsed as the renderer would.
fn parse_and_use(bytes: &[u8]) {
    if let Ok(g) = parse_ply(bytes) {
        let p = g.to_render_params();
        assert_eq!(p.opacities.len(), g.len());
    }
}

#[test]
fn the_seeds_are_valid() {
    assert_eq!(parse_ply(&binary_ply()).unwrap().len(), 2);
    assert_eq!(parse_ply(ASCII_PLY.as_bytes()).unwrap().len(), 2);
    parse_camera_json(CAMERA).unwrap();
}

proptest! {
    #![proptest_config(mutate::config(3000))]

    /// Guards the binary PLY reader against damaged files (a count larger than the data, a
    /// cut record, a changed property type): an error, never a panic or a huge allocation.
    #[test]
    fn damaged_binary_ply_never_panics(edits in mutate::edits()) {
        parse_and_use(&mutate::apply(&binary_ply(), &edits));
    }

    /// Guards the ascii PLY reader and the header parser against damaged text.
    #[test]
    fn damaged_ascii_ply_never_panics(edits in mutate::edits()) {
        parse_and_use(&mutate::apply(ASCII_PLY.as_bytes(), &edits));
    }

    /// Guards the camera JSON reader: damaged files give an error or a camera that passed
    /// validation (finite, positive focal lengths, an invertible rotation).
    #[test]
    fn damaged_camera_json_never_panics(edits in mutate::edits()) {
        let bytes = mutate::apply(CAMERA.as_bytes(), &edits);
        if let Ok(c) = parse_camera_json(&String::from_utf8_lossy(&bytes)) {
            prop_assert!(c.fx.is_finite() && c.fx > 0.0 && c.fy.is_finite() && c.fy > 0.0);
            prop_assert!(c.width > 0 && c.height > 0);
        }
    }
}
