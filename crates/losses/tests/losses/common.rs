//! Shared helpers: the metrics fixture, a seeded RNG, tensor construction and readback.

use std::path::{Path, PathBuf};

use burn::store::{ModuleStore, SafetensorsStore};
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_losses::lpips::{QuantizedKeys, WeightKeys};
use envision4d_losses::{HostImages, LpipsNet, LpipsWeights};

/// `shared/fixtures/metrics.safetensors`, beside the clone (CI layout).
pub const FIXTURE: &str = "../../../shared/fixtures/metrics.safetensors";

/// The fixture path; panics (fails the test) with the path when it is missing.
pub fn fixture() -> PathBuf {
    let p = crate::paths::manifest_dir().join(FIXTURE);
    assert!(
        p.is_file(),
        "metrics fixture missing: {} (expected shared/fixtures beside the clone)",
        p.display()
    );
    p
}

/// One fixture tensor as f64 values and its shape.
pub fn read(path: &Path, key: &str) -> (Vec<f64>, Vec<usize>) {
    let mut store = SafetensorsStore::from_file(path);
    let t = store
        .get_tensor(key)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .unwrap_or_else(|| panic!("{}: no tensor `{key}`", path.display()));
    let data = burn::store::bridge::to_data(t).expect("tensor data");
    let shape = data.shape().to_vec();
    (data.try_into_vec_as::<f64>().expect("float data"), shape)
}

/// Fixture images as host images.
pub fn fixture_images(key: &str) -> HostImages {
    let (v, s) = read(&fixture(), key);
    HostImages::new("fixture images", v, [s[0], s[1], s[2], s[3]]).unwrap()
}

/// The fixture's LPIPS VGG weights (int8 × step backbone, real lin layers).
pub fn fixture_vgg_weights() -> LpipsWeights {
    let keys = WeightKeys {
        prefix: "lpips_vgg/weights/".into(),
        quantized: Some(QuantizedKeys {
            values_prefix: "lpips_vgg/weights_int8/".into(),
            step_prefix: "lpips_vgg/weights_step/".into(),
        }),
    };
    LpipsWeights::from_safetensors_with(&fixture(), LpipsNet::Vgg, &keys).expect("fixture vgg")
}

/// Test data from the test kit's SplitMix64 stream.
pub struct Rng(envision4d_splat::testkit::SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(envision4d_splat::testkit::SplitMix64::new(seed))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn vec(&mut self, n: usize, lo: f64, hi: f64) -> Vec<f64> {
        (0..n).map(|_| self.range(lo, hi)).collect()
    }
}

/// A tensor from f64 values in `dtype` on `device`.
pub fn tensor<const D: usize>(
    v: &[f64],
    shape: [usize; D],
    device: &Device,
    dtype: DType,
) -> Tensor<D> {
    Tensor::from_data(
        TensorData::new(v.to_vec(), shape).convert_dtype(dtype),
        (device, dtype),
    )
}

/// All values of a tensor as f64.
pub fn values<const D: usize>(t: Tensor<D>) -> Vec<f64> {
    t.into_data().try_into_vec_as::<f64>().unwrap()
}

/// Largest absolute and relative difference.
pub fn max_diffs(a: &[f64], b: &[f64]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold((0.0f64, 0.0f64), |(ma, mr), (x, y)| {
        let d = (x - y).abs();
        (ma.max(d), mr.max(d / y.abs().max(1e-300)))
    })
}

/// Write f32 tensors as a safetensors file (8-byte header length, JSON header, data), the
/// layout `scripts/export_lpips_weights.py` produces.
pub fn write_safetensors(path: &Path, tensors: &[(String, Vec<usize>, Vec<f32>)]) {
    let mut header = String::from("{");
    let mut offset = 0usize;
    for (i, (name, shape, data)) in tensors.iter().enumerate() {
        let end = offset + 4 * data.len();
        let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
        header += &format!(
            "{}\"{name}\":{{\"dtype\":\"F32\",\"shape\":[{}],\"data_offsets\":[{offset},{end}]}}",
            if i == 0 { "" } else { "," },
            dims.join(",")
        );
        offset = end;
    }
    header += "}";
    while header.len() % 8 != 0 {
        header.push(' ');
    }
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(header.as_bytes());
    for (_, _, data) in tensors {
        for v in data {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// LPIPS weights as the export script names them (no prefix, plain f32, scaling buffers).
pub fn export_layout(w: &LpipsWeights, shift: [f32; 3]) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    let mut out = vec![
        (
            "scaling_layer.shift".to_owned(),
            vec![1, 3, 1, 1],
            shift.to_vec(),
        ),
        (
            "scaling_layer.scale".to_owned(),
            vec![1, 3, 1, 1],
            envision4d_losses::lpips::SCALING_SCALE.to_vec(),
        ),
    ];
    let indices: &[(usize, usize)] = match w.net {
        LpipsNet::Vgg => &[
            (1, 0),
            (1, 2),
            (2, 5),
            (2, 7),
            (3, 10),
            (3, 12),
            (3, 14),
            (4, 17),
            (4, 19),
            (4, 21),
            (5, 24),
            (5, 26),
            (5, 28),
        ],
        LpipsNet::Alex => &[(1, 0), (2, 3), (3, 6), (4, 8), (5, 10)],
    };
    for (&(s, i), c) in indices.iter().zip(&w.convs) {
        out.push((
            format!("net.slice{s}.{i}.weight"),
            c.weight.shape.clone(),
            c.weight.data.clone(),
        ));
        out.push((
            format!("net.slice{s}.{i}.bias"),
            c.bias.shape.clone(),
            c.bias.data.clone(),
        ));
    }
    for (k, l) in w.lins.iter().enumerate() {
        out.push((
            envision4d_losses::lpips::lin_key(k),
            l.shape.clone(),
            l.data.clone(),
        ));
    }
    out
}
