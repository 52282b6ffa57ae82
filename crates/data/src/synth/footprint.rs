//! How large moving objects appear in a rendered clip, in pixels and in ViT patches: what
//! decides the resolution of the motion suite (a mover must span several 14x14 patches for
//! the motion head to see its shape, not one blurred token).

use super::ClipRender;

/// DINOv2 patch side in pixels (the backbone's tokeniser, paper §3.1).
pub const PATCH_PX: usize = 14;

/// Footprint of the moving objects of a clip (frames where they move and are visible).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Footprint {
    /// Moving (object, frame) sightings counted.
    pub sightings: usize,
    /// Mean pixels per sighting.
    pub mean_px: f64,
    /// Mean bounding-box width and height per sighting, pixels.
    pub mean_box: (f64, f64),
    /// Median pixels per sighting.
    pub median_px: f64,
}

impl Footprint {
    /// Mean area of a sighting in patches (`PATCH_PX²` pixels each).
    pub fn mean_patches(&self) -> f64 {
        self.mean_px / (PATCH_PX * PATCH_PX) as f64
    }
}

/// Pixels and boxes of every moving track in every frame of `clip`.
pub fn footprint(clip: &ClipRender) -> Footprint {
    let w = clip.config.width;
    let mut areas = Vec::new();
    let (mut bw, mut bh) = (0.0, 0.0);
    for (t, f) in clip.frames.iter().enumerate() {
        for tr in clip
            .tracks
            .iter()
            .filter(|tr| tr.states.iter().any(|s| s.t == t && s.moving))
        {
            let (mut n, mut x0, mut x1, mut y0, mut y1) = (0usize, usize::MAX, 0, usize::MAX, 0);
            for (p, _) in f
                .instance
                .iter()
                .enumerate()
                .filter(|(_, id)| **id == tr.id)
            {
                let (x, y) = (p % w, p / w);
                n += 1;
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
            if n > 0 {
                areas.push(n as f64);
                bw += (x1 - x0 + 1) as f64;
                bh += (y1 - y0 + 1) as f64;
            }
        }
    }
    if areas.is_empty() {
        return Footprint::default();
    }
    let k = areas.len() as f64;
    let mean_px = areas.iter().sum::<f64>() / k;
    areas.sort_by(f64::total_cmp);
    Footprint {
        sightings: areas.len(),
        mean_px,
        mean_box: (bw / k, bh / k),
        median_px: areas[areas.len() / 2],
    }
}
