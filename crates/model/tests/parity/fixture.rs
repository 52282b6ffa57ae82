//! Reading golden fixtures: tensors by key, and weights into modules by prefix.

use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::weights::{load_weights, Missing, Unexpected};
use safetensors::SafeTensors;
use std::path::PathBuf;

pub struct Fixture {
    pub path: PathBuf,
    bytes: Vec<u8>,
}

impl Fixture {
    /// Opens `../shared/fixtures/<name>`; a missing file fails the test, naming the path.
    pub fn open(name: &str) -> Self {
        let path = crate::paths::manifest_dir()
            .join("../../../shared/fixtures")
            .join(name);
        let bytes = std::fs::read(&path)
            .unwrap_or_else(|e| panic!("fixture {} is required: {e}", path.display()));
        Fixture { path, bytes }
    }

    fn view(&self) -> SafeTensors<'_> {
        SafeTensors::deserialize(&self.bytes).expect("valid safetensors")
    }

    pub fn shape(&self, key: &str) -> Vec<usize> {
        self.view()
            .tensor(key)
            .unwrap_or_else(|_| panic!("fixture key {key} missing"))
            .shape()
            .to_vec()
    }

    pub fn f32s(&self, key: &str) -> Vec<f32> {
        let st = self.view();
        let t = st
            .tensor(key)
            .unwrap_or_else(|_| panic!("fixture key {key} missing"));
        match t.dtype() {
            safetensors::Dtype::F32 => t
                .data()
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect(),
            safetensors::Dtype::F64 => t
                .data()
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().unwrap()) as f32)
                .collect(),
            d => panic!("{key}: unexpected dtype {d:?}"),
        }
    }

    pub fn i64s(&self, key: &str) -> Vec<i64> {
        let st = self.view();
        let t = st
            .tensor(key)
            .unwrap_or_else(|_| panic!("fixture key {key} missing"));
        assert_eq!(t.dtype(), safetensors::Dtype::I64, "{key}");
        t.data()
            .chunks_exact(8)
            .map(|b| i64::from_le_bytes(b.try_into().unwrap()))
            .collect()
    }

    pub fn tensor<const D: usize>(&self, key: &str, device: &Device) -> Tensor<D> {
        let shape = self.shape(key);
        assert_eq!(shape.len(), D, "{key}: rank");
        Tensor::from_data(
            (TensorData::new(self.f32s(key), shape), DType::F32).0,
            device,
        )
    }

    /// Loads every parameter of `module` from `<prefix><official key>`; all must be present.
    pub fn load<M: burn::module::Module + burn::store::ModuleSnapshot>(
        &self,
        module: &mut M,
        prefix: &str,
    ) {
        let report = load_weights(
            module,
            &self.path,
            prefix,
            Missing::Reject,
            Unexpected::Reject,
        )
        .unwrap_or_else(|e| panic!("loading {prefix}*: {e}"));
        assert!(report.applied > 0, "nothing loaded under {prefix}");
    }
}

impl Fixture {
    /// Checks `got` against `expected/<key>` (see [`assert_close`]).
    pub fn expect<const D: usize>(&self, key: &str, got: Tensor<D>, rel: f32, abs: f32) -> f32 {
        assert_close(
            key,
            flat(got),
            &self.f32s(&format!("expected/{key}")),
            rel,
            abs,
        )
    }

    /// The tiny Envision4D with every weight of this fixture loaded strictly (`weights/`).
    pub fn tiny_model(&self, device: &Device) -> envision4d_model::Envision4d {
        let mut m =
            envision4d_model::Envision4d::new(&envision4d_model::ModelConfig::tiny(), device);
        load_weights(
            &mut m,
            &self.path,
            "weights/",
            Missing::Reject,
            Unexpected::Reject,
        )
        .unwrap_or_else(|e| panic!("{e}"));
        m
    }
}

/// Asserts `|got - want| <= rel * max|want| + abs` elementwise and returns the worst ratio.
pub fn assert_close(what: &str, got: Tensor<1>, want: &[f32], rel: f32, abs: f32) -> f32 {
    let got: Vec<f32> = got
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap();
    assert_eq!(got.len(), want.len(), "{what}: length");
    let scale = want.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let tol = rel * scale + abs;
    let mut worst = 0.0f32;
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let d = (g - w).abs();
        assert!(
            d <= tol,
            "{what}[{i}]: got {g}, want {w} (|diff| {d:e} > tol {tol:e}, max|ref| {scale})"
        );
        worst = worst.max(d / scale.max(1e-30));
    }
    eprintln!("{what}: max |diff| / max|ref| = {worst:.2e}");
    worst
}

/// Flattens any tensor for comparison.
pub fn flat<const D: usize>(t: Tensor<D>) -> Tensor<1> {
    let n = t.shape().num_elements();
    t.reshape([n])
}

/// Unit-case tolerance of the fixtures README: `1e-5 * max|ref| + 1e-6`.
pub const UNIT_REL: f32 = 1e-5;
pub const UNIT_ABS: f32 = 1e-6;
