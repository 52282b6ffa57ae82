//! How the shards' gradients become one: gathered on the first device, or all-reduced on
//! the devices by Burn's collectives.

use crate::error::{Result, TrainError};
use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{GradientsAccumulator, GradientsParams};
use burn::tensor::distributed::{all_reduce, CollectiveTensor, ReduceOperation};
use burn::tensor::{Device, Tensor};
use envision4d_model::Envision4d;

/// How a data-parallel step combines the shards' gradients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GradientReduce {
    /// Every shard's gradients are moved to the first device (`GradientsParams::to_device`)
    /// and summed there (`GradientsAccumulator`). Works on every backend.
    #[default]
    Gather,
    /// Burn's collective all-reduce (`burn::tensor::distributed::all_reduce`, NCCL on CUDA):
    /// the devices sum the gradients among themselves, one host thread per device. Burn 0.22
    /// implements collectives on CUDA only (on flex or wgpu devices cubecl panics), so the
    /// CLI chooses this only when every `--devices` entry is a CUDA device.
    AllReduce,
}

/// The shards' gradients (shard k computed on `devices[k]`) summed into one set on
/// `devices[0]`. `model` is the trainer's model: its parameter order is the order in which
/// every device submits its collectives.
pub(crate) fn combine(
    mode: GradientReduce,
    model: &Envision4d,
    shards: Vec<GradientsParams>,
    devices: &[Device],
) -> Result<GradientsParams> {
    match mode {
        GradientReduce::Gather => Ok(gather(model, shards, &devices[0])),
        GradientReduce::AllReduce => all_reduced(model, shards, devices),
    }
}

/// Sums on `main`, adding the shards in device order (a fixed order, so the sum is the
/// same from run to run).
fn gather(model: &Envision4d, shards: Vec<GradientsParams>, main: &Device) -> GradientsParams {
    let mut acc = GradientsAccumulator::<Envision4d>::new();
    for gp in shards {
        acc.accumulate(model, gp.to_device(main, model));
    }
    acc.grads()
}

/// Which parameters (in the model's visiting order) have a gradient in `grads`.
fn present(model: &Envision4d, grads: &GradientsParams) -> Vec<bool> {
    struct Present<'a>(&'a GradientsParams, Vec<bool>);
    impl ModuleVisitor for Present<'_> {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.1.push(self.0.get::<D>(p.id).is_some());
        }
    }
    let mut v = Present(grads, Vec::new());
    model.visit(&mut v);
    v.1
}

/// Submits one all-reduce per gradient, in the model's parameter order, then resolves them.
struct Submit<'a> {
    grads: &'a mut GradientsParams,
    devices: &'a [Device],
    pending: Vec<Box<dyn FnOnce(&mut GradientsParams)>>,
}

impl ModuleVisitor for Submit<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(p.id) {
            let reduced: CollectiveTensor<D> =
                all_reduce(g, ReduceOperation::Sum, self.devices.to_vec());
            let id = p.id;
            self.pending
                .push(Box::new(move |gp| gp.register::<D>(id, reduced.resolve())));
        }
    }
}

/// Every device all-reduces its own gradients, one host thread per device: NCCL joins a
/// group only when all its ranks call in, so one thread submitting for every device in turn
/// would wait forever on the first. All devices must submit the same collectives in the
/// same order, so the set of parameters with a gradient is checked to be equal first (a
/// mismatch would hang the group, not fail it).
fn all_reduced(
    model: &Envision4d,
    shards: Vec<GradientsParams>,
    devices: &[Device],
) -> Result<GradientsParams> {
    let first = present(model, &shards[0]);
    if let Some(k) = shards.iter().position(|g| present(model, g) != first) {
        return Err(TrainError::Internal(format!(
            "shard {k} has gradients for other parameters than shard 0: no all-reduce"
        )));
    }
    let reduced = std::thread::scope(|s| {
        let handles: Vec<_> = shards
            .into_iter()
            .map(|mut grads| {
                s.spawn(move || {
                    let mut v = Submit {
                        grads: &mut grads,
                        devices,
                        pending: Vec::new(),
                    };
                    model.visit(&mut v);
                    for resolve in std::mem::take(&mut v.pending) {
                        resolve(&mut grads);
                    }
                    grads
                })
            })
            .collect();
        // Every thread is joined before any failure is looked at (a scope with an unjoined
        // panicked thread panics itself).
        let joined: Vec<_> = handles.into_iter().map(|h| h.join()).collect();
        joined
            .into_iter()
            .map(|r| r.map_err(|p| panic_error("all-reduce", p)))
            .collect::<Result<Vec<_>>>()
    })?;
    // Every device now holds the sum; the first device's copy is the one applied.
    reduced
        .into_iter()
        .next()
        .ok_or_else(|| TrainError::Internal("no shard to all-reduce".into()))
}

/// A worker thread's panic as an error naming what it was doing.
pub(crate) fn panic_error(what: &str, payload: Box<dyn std::any::Any + Send>) -> TrainError {
    let msg = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    TrainError::Internal(format!("a data-parallel {what} thread panicked: {msg}"))
}
