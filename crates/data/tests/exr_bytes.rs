//! EXR output must be a function of its pixels: the synthetic world promises byte-identical
//! files for a seed, and users diff and hash outputs.

use envision4d_data::exr_io::{read_gray, write_gray, FloatMap};

/// Guards EXR bytes that changed from run to run: with parallel compression the chunks were
/// written in the order they finished, so the same depth map gave different files (the
/// pixels were equal). Many chunks (a tall map) and repeated writes make any reordering show.
#[test]
fn the_same_map_always_gives_the_same_bytes() {
    let (width, height) = (96, 640);
    let data: Vec<f32> = (0..width * height)
        .map(|i| ((i * 7919) % 1013) as f32 * 0.37 + (i % 17) as f32)
        .collect();
    let map = FloatMap {
        width,
        height,
        channels: 1,
        data,
    };
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.exr");
    write_gray(&first, &map).unwrap();
    let bytes = std::fs::read(&first).unwrap();
    for k in 0..6 {
        let again = dir.path().join(format!("again-{k}.exr"));
        write_gray(&again, &map).unwrap();
        assert!(
            std::fs::read(&again).unwrap() == bytes,
            "write {k} differs from the first"
        );
    }
    assert_eq!(read_gray(&first).unwrap().data, map.data);
}
