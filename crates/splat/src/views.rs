//! Which Gaussians each view renders: one scene seen by several cameras, or a different
//! scene per view laid one after another (gsplat's batched Gaussians). The second is what a
//! training step needs: every target frame has its own time-conditioned Gaussians, and
//! rendering them all in one call costs one host readback instead of one per view.

/// The Gaussian rows each view of a render call sees.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ViewSets {
    /// Every view renders all N input rows.
    #[default]
    Shared,
    /// View v renders `rows[v]` consecutive input rows, starting where view v - 1's ended;
    /// the counts sum to N.
    Stacked(Vec<usize>),
}

impl ViewSets {
    /// `(first row, rows)` of view `v` of a call with `n` input rows.
    pub fn range(&self, v: usize, n: usize) -> (usize, usize) {
        match self {
            ViewSets::Shared => (0, n),
            ViewSets::Stacked(rows) => (rows[..v].iter().sum(), rows[v]),
        }
    }

    /// Every view's `(first row, rows)`.
    pub fn ranges(&self, views: usize, n: usize) -> Vec<(usize, usize)> {
        (0..views).map(|v| self.range(v, n)).collect()
    }

    /// Width of the `[V, R, 2]` radii output: N when shared, the largest set when stacked
    /// (shorter sets are zero-padded, i.e. read as culled).
    pub fn radii_rows(&self, n: usize) -> usize {
        match self {
            ViewSets::Shared => n,
            ViewSets::Stacked(rows) => rows.iter().copied().max().unwrap_or(0),
        }
    }

    /// Checks the sets against `views` cameras and `n` input rows.
    pub fn validate(&self, views: usize, n: usize) -> Result<(), String> {
        let ViewSets::Stacked(rows) = self else {
            return Ok(());
        };
        if rows.len() != views {
            return Err(format!(
                "stacked Gaussians: {} per-view sets for {views} cameras",
                rows.len()
            ));
        }
        let total: usize = rows.iter().sum();
        if total != n {
            return Err(format!(
                "stacked Gaussians: the per-view sets hold {total} rows, the inputs {n}"
            ));
        }
        Ok(())
    }
}

/// One render call's camera matrices on the host, as validation read them: row-major f32
/// `viewmats` (16 per view) and `ks` (9 per view). Validation has to read them anyway; the
/// GPU kernels take them from here instead of reading the device a second time in the
/// forward and a third in the backward (each read is a device synchronisation).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HostCameras {
    pub viewmats: std::sync::Arc<[f32]>,
    pub ks: std::sync::Arc<[f32]>,
}
