//! The fused RoPE rotation (one kernel forward, one backward) on wgpu against the rotation
//! in Burn's ops in f64 on the CPU: output and input gradient, with tables per batch element
//! and shared by the batch, head widths from 4 to 128, far positions, inputs near f32's
//! range ends, tables that are constants of another graph (as the recomputed blocks pass
//! them), and more elements than one grid axis of workgroups holds.

use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::rope::{frame_positions, set_fused_rope, RopeTables};
use support::{gpu, host, rel_err, turn, uniform, Unfused};

mod support;

/// Tokens `[b, h, 1 + rows·cols, d]` scaled by `gain`; `shared`: one table row set for the
/// whole batch (`[1, 1, N, d]`), else one per element; `offset` moves every patch position
/// (far positions: large angles); `inner`: the tables live off the autodiff graph.
#[derive(Debug, Clone, Copy)]
struct Case {
    b: usize,
    h: usize,
    grid: [usize; 2],
    d: usize,
    gain: f64,
    shared: bool,
    offset: i64,
    inner: bool,
}

/// Output and input gradient of `sum(rope(x) · w)`.
fn run(case: Case, device: &Device, dtype: DType) -> [Vec<f64>; 2] {
    let positions: Vec<[i64; 2]> = frame_positions(1, case.grid[0], case.grid[1])
        .into_iter()
        .map(|[y, x]| [y + case.offset, x + case.offset])
        .collect();
    let n = positions.len();
    let batches = if case.shared { 1 } else { case.b };
    // The tables are f32 host values either way; the oracle widens them.
    let table_device = if case.inner {
        device.clone().inner()
    } else {
        device.clone()
    };
    let tables = RopeTables::new(&vec![positions; batches], case.d, &table_device).cast(dtype);
    let shape = [case.b, case.h, n, case.d];
    let len = shape.iter().product();
    let tensor = |v: Vec<f64>| {
        Tensor::<4>::from_data(
            TensorData::new(v, shape).convert_dtype(dtype),
            (device, dtype),
        )
    };
    let x = tensor(uniform(len, 1).into_iter().map(|v| v * case.gain).collect()).require_grad();
    let w = tensor(uniform(len, 2));
    let y = tables.apply(x.clone());
    let g = (y.clone() * w).sum().backward();
    [host(y), host(x.grad(&g).expect("a gradient"))]
}

fn cases() -> Vec<Case> {
    let case = Case {
        b: 2,
        h: 3,
        grid: [3, 4],
        d: 16,
        gain: 1.0,
        shared: false,
        offset: 0,
        inner: false,
    };
    vec![
        case,
        Case {
            shared: true,
            ..case
        },
        Case { d: 4, b: 1, ..case },
        Case {
            d: 128,
            h: 2,
            grid: [5, 7],
            ..case
        },
        // Positions past 1000 (angles of thousands of radians), inputs near 1e30 and 1e-30.
        Case {
            offset: 1000,
            ..case
        },
        Case { gain: 1e30, ..case },
        Case {
            gain: 1e-30,
            ..case
        },
        // Tables of a recomputed block: inner tensors beside autodiff tokens.
        Case {
            inner: true,
            ..case
        },
        // 4 · 4 · 1,025 · 1,024 = 16.8M elements: past 65,535 workgroups (one grid axis)
        // wherever a workgroup holds 256 units or fewer, so the grid is 2-D.
        Case {
            b: 4,
            h: 4,
            grid: [32, 32],
            d: 1024,
            shared: true,
            ..case
        },
    ]
}

/// Guards the fused rotation and its wiring (the quarter partner, the sine's sign per
/// quarter, the table row per batch element or shared, the VJP reading the partner's sine,
/// tables off the graph, the 2-D grid): on wgpu it equals the rotation in f64 to f32
/// rounding and Burn's ops on the same device to an ulp or two.
#[test]
fn fused_rope_equals_f64_rotation_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let oracle = Device::flex().autodiff();
    for case in cases() {
        let want = run(case, &oracle, DType::F64);
        let fused = run(case, &device, DType::F32);
        let burn = {
            let _off = Unfused::new(set_fused_rope);
            run(case, &device, DType::F32)
        };
        for (i, name) in ["y", "dx"].into_iter().enumerate() {
            let (e, e_burn) = (rel_err(&fused[i], &want[i]), rel_err(&burn[i], &want[i]));
            let apart = rel_err(&fused[i], &burn[i]);
            println!("{case:?} {name}: fused {e:.2e}, Burn's ops {e_burn:.2e}, apart {apart:.2e}");
            assert!(e <= 3e-7, "{case:?}: {name} relative error {e:.3e}");
            assert!(
                apart <= 3e-7,
                "{case:?}: {name} fused and Burn's ops {apart:.3e} apart"
            );
        }
    }
}

/// Guards the launches the op exists for: one rotation forward and backward on wgpu takes
/// at least five fewer kernels fused (two) than in Burn's ops (a flip, two products and a
/// sum each way), with the same result.
#[test]
fn fused_rope_launches_fewer_kernels() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let case = cases()[0];
    let _ = run(case, &device, DType::F32);
    let (fused, on) = count_launches(false, || run(case, &device, DType::F32));
    let (burn, off) = {
        let _off = Unfused::new(set_fused_rope);
        count_launches(false, || run(case, &device, DType::F32))
    };
    let (on, off) = (on.total(), off.total());
    println!("launches of one rotation, forward and backward: fused {on}, Burn's ops {off}");
    assert!(
        on + 5 <= off,
        "fused {on} launches against Burn's ops {off}"
    );
    for i in 0..2 {
        assert!(rel_err(&fused[i], &burn[i]) <= 3e-7);
    }
}
