//! Float32 EXR maps: single-channel (`Y`, e.g. z-depth) and three-channel (`X`, `Y`, `Z`,
//! e.g. scene flow). Written atomically, uncompressed-size independent of content order.

use crate::atomic::write_with;
use crate::error::{DataError, Result};
use std::path::Path;

/// A row-major float map with `channels` values per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatMap {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<f32>,
}

impl FloatMap {
    pub fn get(&self, row: usize, col: usize, ch: usize) -> f32 {
        self.data[(row * self.width + col) * self.channels + ch]
    }
}

const GRAY: &str = "Y";
const XYZ: [&str; 3] = ["X", "Y", "Z"];

/// Writes a one-channel map as float32 EXR (channel `Y`).
pub fn write_gray(path: &Path, map: &FloatMap) -> Result<()> {
    use exr::prelude::*;
    let m = map;
    write_with(path, |tmp| {
        let channels = SpecificChannels::build()
            .with_channel(GRAY)
            .with_pixel_fn(|p: Vec2<usize>| (m.get(p.y(), p.x(), 0),));
        Image::from_channels((m.width, m.height), channels)
            .write()
            // In order: parallel compression writes the chunks as they finish, so the same
            // image gave different bytes from run to run.
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| e.to_string())
    })
}

/// Writes a three-channel map as float32 EXR (channels `X`, `Y`, `Z`).
pub fn write_xyz(path: &Path, map: &FloatMap) -> Result<()> {
    use exr::prelude::*;
    let m = map;
    write_with(path, |tmp| {
        let channels = SpecificChannels::build()
            .with_channel(XYZ[0])
            .with_channel(XYZ[1])
            .with_channel(XYZ[2])
            .with_pixel_fn(|p: Vec2<usize>| {
                (
                    m.get(p.y(), p.x(), 0),
                    m.get(p.y(), p.x(), 1),
                    m.get(p.y(), p.x(), 2),
                )
            });
        Image::from_channels((m.width, m.height), channels)
            .write()
            // In order: parallel compression writes the chunks as they finish, so the same
            // image gave different bytes from run to run.
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| e.to_string())
    })
}

/// Reads the named channels of the first layer of an EXR file into one map.
pub fn read_channels(path: &Path, names: &[&str]) -> Result<FloatMap> {
    let bad = |msg: String| DataError::gt(path, msg);
    if !path.is_file() {
        return Err(bad("file not found".into()));
    }
    let img =
        exr::prelude::read_first_flat_layer_from_file(path).map_err(|e| bad(e.to_string()))?;
    let size = img.layer_data.size;
    let (width, height) = (size.0, size.1);
    let list = &img.layer_data.channel_data.list;
    let mut planes = Vec::with_capacity(names.len());
    for name in names {
        let ch = list
            .iter()
            .find(|c| c.name == **name)
            .ok_or_else(|| bad(format!("no channel {name:?}")))?;
        planes.push(ch.sample_data.values_as_f32().collect::<Vec<f32>>());
    }
    let mut data = vec![0.0; width * height * names.len()];
    for (c, plane) in planes.iter().enumerate() {
        if plane.len() != width * height {
            return Err(bad(format!(
                "channel {} has {} samples",
                names[c],
                plane.len()
            )));
        }
        for (p, v) in plane.iter().enumerate() {
            data[p * names.len() + c] = *v;
        }
    }
    Ok(FloatMap {
        width,
        height,
        channels: names.len(),
        data,
    })
}

pub fn read_gray(path: &Path) -> Result<FloatMap> {
    read_channels(path, &[GRAY])
}

pub fn read_xyz(path: &Path) -> Result<FloatMap> {
    read_channels(path, &XYZ)
}
