//! One pair's motion as pictures: the true displacement length, the predicted one and the
//! end-point error per pixel, on the prediction grid, in metres (`eval --motion-images`).
//! The pair is the longest extrapolation from the newest context frame: source `T_c − 1`,
//! target `N − 1`.

use crate::motion::Aligned;

/// Per-pixel lengths (metres) of one (source, target) pair, row-major `H·W`; `NaN` where the
/// pixel has no truth (sky), in `truth` and `error`.
#[derive(Debug, Clone, PartialEq)]
pub struct PairMaps {
    pub source: usize,
    pub target: usize,
    /// `(H, W)` of the prediction grid.
    pub size: (usize, usize),
    pub truth: Vec<f32>,
    pub predicted: Vec<f32>,
    pub error: Vec<f32>,
}

/// The maps of pair (`T_c − 1`, `N − 1`) of an aligned clip.
pub(crate) fn pair_maps(a: &Aligned) -> PairMaps {
    let (i, j) = (a.pred.context - 1, a.pred.frames - 1);
    let mut maps = PairMaps {
        source: i,
        target: j,
        size: a.pred.grid,
        truth: Vec::with_capacity(a.pixels()),
        predicted: Vec::with_capacity(a.pixels()),
        error: Vec::with_capacity(a.pixels()),
    };
    for (k, d) in a.truth(i, j).into_iter().enumerate() {
        let p = a.predicted(i, j, k);
        maps.predicted.push(p.length() as f32);
        maps.truth.push(d.map_or(f32::NAN, |d| d.length() as f32));
        maps.error
            .push(d.map_or(f32::NAN, |d| (p - d).length() as f32));
    }
    maps
}

impl PairMaps {
    /// The upper end of a shared colour scale: the 99th percentile of the true lengths
    /// (so one far outlier does not wash out the rest), at least `floor` metres.
    pub fn scale_max(&self, floor: f32) -> f32 {
        let mut v: Vec<f32> = self
            .truth
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .collect();
        if v.is_empty() {
            return floor;
        }
        v.sort_by(f32::total_cmp);
        v[(v.len() - 1) * 99 / 100].max(floor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the scale: the 99th percentile of the finite true lengths, never below the
    /// floor, NaN (sky) ignored.
    #[test]
    fn scale_is_a_high_percentile_with_a_floor() {
        let mut truth: Vec<f32> = (1..=100).map(|v| v as f32 / 10.0).collect();
        truth.push(f32::NAN);
        let m = PairMaps {
            source: 1,
            target: 7,
            size: (1, truth.len()),
            predicted: vec![0.0; truth.len()],
            error: truth.clone(),
            truth,
        };
        assert_eq!(m.scale_max(0.5), 9.9);
        assert_eq!(m.scale_max(20.0), 20.0);
    }
}
