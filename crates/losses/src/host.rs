//! Host-side image and depth batches for the evaluation metrics.
//!
//! Metrics run on the host in f64: they are not differentiated, the images are small next to
//! the model, and f64 keeps the results within the reference's own float32-vs-float64 spread
//! (see the fixtures README, §3). Construction validates shape and finiteness once, so every
//! metric can assume clean input.

use burn::tensor::{Tensor, TensorData};

use crate::error::{ensure_finite, LossError, Result};

/// A batch of images `[N, C, H, W]` (row-major), values nominally in [0, 1], all finite.
#[derive(Debug, Clone, PartialEq)]
pub struct HostImages {
    data: Vec<f64>,
    shape: [usize; 4],
}

impl HostImages {
    /// Wrap row-major `[N, C, H, W]` values. Errors on a length mismatch, an empty
    /// dimension or a non-finite value (named by `what`).
    pub fn new(what: &'static str, data: Vec<f64>, shape: [usize; 4]) -> Result<Self> {
        if shape.contains(&0) || shape.iter().product::<usize>() != data.len() {
            return Err(LossError::BadShape {
                what,
                expected: "non-empty [N, C, H, W] matching the data length",
                got: shape.to_vec(),
            });
        }
        ensure_finite(what, &data)?;
        Ok(Self { data, shape })
    }

    /// Read a `[N, C, H, W]` Burn tensor back to the host (any float dtype).
    pub fn from_tensor(what: &'static str, images: Tensor<4>) -> Result<Self> {
        let shape = images.dims();
        let data = read_f64(what, images.into_data())?;
        Self::new(what, data, shape)
    }

    /// `[N, C, H, W]`.
    pub fn shape(&self) -> [usize; 4] {
        self.shape
    }

    /// All values, row-major.
    pub fn data(&self) -> &[f64] {
        &self.data
    }

    /// Image `n` as a `[C, H, W]` slice. Panics if `n >= N` (an index bug, not bad data).
    pub fn image(&self, n: usize) -> &[f64] {
        let len = self.shape[1] * self.shape[2] * self.shape[3];
        &self.data[n * len..(n + 1) * len]
    }

    /// Rows `[top, top+h)` and columns `[left, left+w)` of every channel of every image.
    pub(crate) fn window(&self, top: usize, h: usize, left: usize, w: usize) -> Self {
        let [n, c, height, width] = self.shape;
        let mut data = Vec::with_capacity(n * c * h * w);
        for plane in 0..n * c {
            for y in top..top + h {
                let row = plane * height * width + y * width;
                data.extend_from_slice(&self.data[row + left..row + left + w]);
            }
        }
        Self {
            data,
            shape: [n, c, h, w],
        }
    }
}

/// A batch of depth maps `[N, H, W]`. Values may be any finite number; which pixels count is
/// decided by the metric (ground truth > 0).
#[derive(Debug, Clone, PartialEq)]
pub struct HostDepths {
    data: Vec<f64>,
    shape: [usize; 3],
}

impl HostDepths {
    /// Wrap row-major `[N, H, W]` values; errors like [`HostImages::new`].
    pub fn new(what: &'static str, data: Vec<f64>, shape: [usize; 3]) -> Result<Self> {
        if shape.contains(&0) || shape.iter().product::<usize>() != data.len() {
            return Err(LossError::BadShape {
                what,
                expected: "non-empty [N, H, W] matching the data length",
                got: shape.to_vec(),
            });
        }
        ensure_finite(what, &data)?;
        Ok(Self { data, shape })
    }

    /// Read a `[N, H, W]` Burn tensor back to the host.
    pub fn from_tensor(what: &'static str, depths: Tensor<3>) -> Result<Self> {
        let shape = depths.dims();
        let data = read_f64(what, depths.into_data())?;
        Self::new(what, data, shape)
    }

    /// `[N, H, W]`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// Map `n` as an `[H, W]` slice. Panics if `n >= N` (an index bug, not bad data).
    pub fn map(&self, n: usize) -> &[f64] {
        let len = self.shape[1] * self.shape[2];
        &self.data[n * len..(n + 1) * len]
    }

    /// Crop every map to rows `[top, top+h)`, columns `[left, left+w)`.
    pub(crate) fn window(&self, top: usize, h: usize, left: usize, w: usize) -> Self {
        let [n, height, width] = self.shape;
        let mut data = Vec::with_capacity(n * h * w);
        for m in 0..n {
            for y in top..top + h {
                let row = m * height * width + y * width;
                data.extend_from_slice(&self.data[row + left..row + left + w]);
            }
        }
        Self {
            data,
            shape: [n, h, w],
        }
    }
}

/// Convert tensor data of any float dtype to f64 values.
pub(crate) fn read_f64(what: &'static str, data: TensorData) -> Result<Vec<f64>> {
    data.try_into_vec_as::<f64>()
        .map_err(|e| LossError::Readback {
            what,
            reason: format!("{e:?}"),
        })
}
