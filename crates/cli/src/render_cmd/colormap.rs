//! Colour coding for viewing (the EXR files keep the values): depth through a viridis-like
//! ramp on inverse depth, scene flow as a direction colour like a normal map.

/// Viridis sampled at 0, 1/4, 1/2, 3/4, 1 (matplotlib's published colours, sRGB 8-bit);
/// linear between them is close enough for a preview and needs no table.
const RAMP: [[u8; 3]; 5] = [
    [68, 1, 84],
    [59, 82, 139],
    [33, 145, 140],
    [94, 201, 98],
    [253, 231, 37],
];
/// Pixels with less accumulated opacity show no surface: they are drawn black instead of the
/// meaningless depth of a nearly empty pixel.
pub const DEPTH_ALPHA_MIN: f32 = 0.5;
/// Inverse-depth percentiles mapped to the ends of the ramp, so a few stray near splats do not
/// squeeze the rest of the image into one colour.
const LOW_PERCENTILE: f64 = 0.02;
const HIGH_PERCENTILE: f64 = 0.98;

/// The ramp at `t` in [0, 1] (clamped), as RGB in [0, 1].
pub fn ramp(t: f32) -> [f32; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (RAMP.len() - 1) as f32;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f32;
    std::array::from_fn(|c| {
        let (a, b) = (RAMP[i][c] as f32, RAMP[i + 1][c] as f32);
        (a + (b - a) * f) / 255.0
    })
}

/// Colours `depth` (row-major, one value per pixel): near is bright, far is dark, pixels with
/// `alpha < DEPTH_ALPHA_MIN` or a non-positive depth are black. Returns RGB in [0, 1].
pub fn depth_colors(depth: &[f32], alpha: &[f32]) -> Vec<f32> {
    let valid = |i: usize| alpha[i] >= DEPTH_ALPHA_MIN && depth[i].is_finite() && depth[i] > 0.0;
    let mut inv: Vec<f32> = (0..depth.len())
        .filter(|&i| valid(i))
        .map(|i| 1.0 / depth[i])
        .collect();
    inv.sort_by(f32::total_cmp);
    let pick = |q: f64| inv[((inv.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = if inv.is_empty() {
        (0.0, 1.0)
    } else {
        (pick(LOW_PERCENTILE), pick(HIGH_PERCENTILE))
    };
    let span = if hi > lo { hi - lo } else { 1.0 };
    (0..depth.len())
        .flat_map(|i| {
            if valid(i) {
                ramp((1.0 / depth[i] - lo) / span)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// Colours a 3-vector field (`xyz` per pixel) like a normal map: `0.5 + 0.5 · d / scale`, with
/// `scale = max(max |d|, floor)`; zero is mid-grey. The floor (the dynamic threshold) keeps
/// sub-threshold noise of a static frame near grey instead of stretching it to full colour.
pub fn flow_colors(flow: &[f32], floor: f32) -> Vec<f32> {
    let norm = |d: &[f32]| d.iter().map(|v| v * v).sum::<f32>().sqrt();
    let max = flow
        .chunks_exact(3)
        .map(norm)
        .filter(|n| n.is_finite())
        .fold(0.0f32, f32::max);
    let scale = max.max(floor).max(f32::MIN_POSITIVE);
    flow.iter()
        .map(|&v| {
            if v.is_finite() {
                0.5 + 0.5 * v / scale
            } else {
                0.5
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the ramp ends and monotone brightness (near must look brighter than far).
    #[test]
    fn ramp_ends_and_order() {
        assert_eq!(ramp(0.0), RAMP[0].map(|v| v as f32 / 255.0));
        assert_eq!(ramp(1.0), RAMP[4].map(|v| v as f32 / 255.0));
        assert_eq!(ramp(f32::NAN), ramp(0.0));
        let luma = |c: [f32; 3]| c[0] + c[1] + c[2];
        for k in 0..10 {
            assert!(luma(ramp(k as f32 / 10.0)) < luma(ramp((k + 1) as f32 / 10.0)));
        }
    }

    /// Guards depth colouring: nearer pixels brighter, empty (low-alpha) pixels black.
    #[test]
    fn depth_near_bright_empty_black() {
        let depth = [1.0, 2.0, 4.0, 3.0];
        let alpha = [1.0, 1.0, 1.0, 0.1];
        let c = depth_colors(&depth, &alpha);
        let luma = |i: usize| c[3 * i] + c[3 * i + 1] + c[3 * i + 2];
        assert!(luma(0) > luma(1) && luma(1) > luma(2));
        assert_eq!(&c[9..12], &[0.0, 0.0, 0.0]);
        assert!(depth_colors(&[1.0], &[0.0]).iter().all(|&v| v == 0.0));
    }

    /// Guards flow colouring: zero motion is grey, the floor bounds the stretch.
    #[test]
    fn flow_grey_at_rest() {
        let c = flow_colors(&[0.0, 0.0, 0.0, 0.01, 0.0, 0.0], 0.1);
        assert_eq!(&c[..3], &[0.5, 0.5, 0.5]);
        assert!((c[3] - 0.55).abs() < 1e-6);
        let c = flow_colors(&[0.0, -2.0, 0.0], 0.1);
        assert_eq!(c, vec![0.5, 0.0, 0.5]);
    }
}
