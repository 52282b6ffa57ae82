//! The device radix sort and scan (wgpu → lavapipe here) against the standard library, and
//! the CPU backend's bodies against the same: random keys, duplicates, all equal, empty and
//! tiny inputs, 2^20 elements, keys at the bit limit, stability.

use burn::tensor::{DType, Device, Int, Tensor, TensorData};
use envision4d_splat::primitives::{exclusive_scan, scan_wrapped, sort_pairs, PrimitiveError};
use envision4d_splat::testkit::{wgpu_test_device, SplitMix64};

fn ints(v: &[u32], device: &Device) -> Tensor<1, Int> {
    // Keys are 32-bit patterns: store them as i32 bit for bit.
    let data: Vec<i32> = v.iter().map(|&x| x as i32).collect();
    Tensor::from_data(TensorData::new(data, [v.len()]), (device, DType::I32))
}

fn words(t: Tensor<1, Int>) -> Vec<u32> {
    let data = t.into_data();
    match data.dtype() {
        DType::I32 => data
            .try_into_vec::<i32>()
            .unwrap()
            .iter()
            .map(|&x| x as u32)
            .collect(),
        _ => data
            .convert::<i64>()
            .try_into_vec::<i64>()
            .unwrap()
            .iter()
            .map(|&x| x as u32)
            .collect(),
    }
}

/// The reference: a stable sort by the low `bits` bits (whole 4-bit passes).
fn expected_sort(keys: &[u32], bits: u32) -> (Vec<u32>, Vec<u32>) {
    let sorted = bits.div_ceil(4) * 4;
    let mask = if sorted >= 32 {
        u32::MAX
    } else {
        (1 << sorted) - 1
    };
    let mut idx: Vec<u32> = (0..keys.len() as u32).collect();
    idx.sort_by_key(|&i| keys[i as usize] & mask);
    (idx.iter().map(|&i| keys[i as usize]).collect(), idx)
}

fn devices() -> Vec<(&'static str, Device)> {
    let mut d = vec![("cpu", Device::default())];
    if let Some(w) = wgpu_test_device() {
        d.push(("wgpu", w));
    }
    d
}

/// Sorts `keys` with values = input positions on every device and compares with the
/// reference: equal keys must keep their positions in order (stability).
fn check_sort(name: &str, keys: &[u32], bits: u32) {
    let (want_k, want_v) = expected_sort(keys, bits);
    let positions: Vec<u32> = (0..keys.len() as u32).collect();
    for (dev_name, device) in devices() {
        let (k, v) = sort_pairs(ints(keys, &device), ints(&positions, &device), bits).unwrap();
        let (k, v) = (words(k), words(v));
        assert_eq!(k.len(), keys.len(), "{name} on {dev_name}: key count");
        if let Some(i) = (0..keys.len()).find(|&i| k[i] != want_k[i] || v[i] != want_v[i]) {
            panic!(
                "{name} on {dev_name}: first difference at {i}: got ({}, {}), want ({}, {})",
                k[i], v[i], want_k[i], want_v[i]
            );
        }
    }
}

fn random(n: usize, seed: u64, modulo: u64) -> Vec<u32> {
    let mut rng = SplitMix64::new(seed);
    (0..n).map(|_| (rng.next_u64() % modulo) as u32).collect()
}

/// Guards a radix sort that loses pairs or reorders equal keys across blocks and passes.
#[test]
fn radix_sort_equals_a_stable_sort() {
    check_sort("random 32-bit", &random(5_000, 1, 1 << 32), 32);
    check_sort("many duplicates", &random(3_000, 2, 8), 3);
    check_sort("all equal", &[7; 2_500], 4);
    check_sort("empty", &[], 32);
    check_sort("one", &[42], 8);
    check_sort("two, reversed", &[9, 3], 4);
    check_sort("two, equal", &[5, 5], 4);
    // Keys at the bit limit: 13 bits sort on 16 (four passes); the top key is 2^13 - 1.
    let mut top = random(4_099, 3, 1 << 13);
    top.extend([(1 << 13) - 1, 0, (1 << 13) - 1]);
    check_sort("at the 13-bit limit", &top, 13);
    check_sort(
        "full 32-bit extremes",
        &[u32::MAX, 0, 1 << 31, u32::MAX, 0x7FFF_FFFF],
        32,
    );
    // Bits beyond `bits` (rounded to a pass) do not order: the high half is ignored.
    check_sort("high bits ignored", &random(2_000, 4, 1 << 32), 16);
}

/// Guards the multi-level paths (many blocks, a scanned block table) at 2^20 keys, at
/// the full key width and at the tile sort's few bits (a 350x518 view's 726 tiles: 12 bits),
/// where the benchmark once timed a million keys in under a millisecond.
#[test]
fn radix_sort_of_a_million_keys() {
    check_sort("2^20 random", &random(1 << 20, 5, 1 << 32), 32);
    for bits in [12u32, 20] {
        check_sort(
            &format!("2^20 keys below 2^{bits}"),
            &random(1 << 20, 6 + u64::from(bits), 1 << bits),
            bits,
        );
    }
}

fn check_scan(name: &str, values: &[u32]) {
    let mut want = vec![0u32];
    for &x in values {
        want.push(want.last().unwrap().wrapping_add(x));
    }
    for (dev_name, device) in devices() {
        let got = words(exclusive_scan(ints(values, &device)).unwrap());
        if let Some(i) = (0..want.len()).find(|&i| got.get(i) != Some(&want[i])) {
            panic!(
                "{name} on {dev_name}: first difference at {i}: got {:?}, want {} (len {} vs {})",
                got.get(i),
                want[i],
                got.len(),
                want.len()
            );
        }
        assert_eq!(got.len(), want.len(), "{name} on {dev_name}: length");
    }
}

/// Guards a scan whose block offsets are wrong at block edges, at two and three levels, or
/// on either side of the in-place block sums' limit.
#[test]
fn exclusive_scan_equals_a_running_sum() {
    check_scan("empty", &[]);
    check_scan("one", &[5]);
    check_scan("two", &[5, 7]);
    // n values scan into n + 1 outputs: up to 16 blocks (n = 16 * 1 024 - 1) the block totals
    // are summed where they are added; from 17 on they are scanned first.
    for n in [
        1_023,
        1_024,
        1_025,
        4_096 + 3,
        16 * 1_024,
        16 * 1_024 + 1,
        40_000,
    ] {
        check_scan(&format!("{n} values"), &random(n, n as u64, 100));
    }
    check_scan("all zero", &[0; 3_000]);
    // 2^20 + 5 values: 1 025 blocks, so the block table itself takes two blocks.
    check_scan("2^20 + 5", &random((1 << 20) + 5, 6, 16));
}

/// Guards the rasterizer's intersection offsets against a silent u32 wrap: a scan whose
/// running sum reaches 2^32 (anywhere, or exactly at the total) is flagged on every device,
/// one that stays below is not, including totals of exactly `u32::MAX`; and the CPU's scan of
/// an i32 tensor whose sums pass `i32::MAX` (it panicked converting them back).
#[test]
fn scan_wrap_is_detected_exactly() {
    let big = 1u32 << 31;
    let cases: [(&str, Vec<u32>, bool); 8] = [
        ("empty", vec![], false),
        ("one max", vec![u32::MAX], false),
        ("max then zeros", vec![u32::MAX, 0, 0], false),
        ("max then one", vec![u32::MAX, 1], true),
        ("exactly 2^32", vec![big, big], true),
        ("wrap mid-way, then zeros", vec![7, u32::MAX, 0, 0, 3], true),
        ("random small", random(5_000, 9, 1 << 16), false),
        // The wrap falls inside the second of three scan blocks.
        (
            "wrap past a block edge",
            {
                let mut v = vec![1u32 << 20; 3_000];
                v[1_500] = u32::MAX - 1_000;
                v
            },
            true,
        ),
    ];
    for (name, values, want) in cases {
        let mut sum = 0u64;
        let truth = values.iter().any(|&x| {
            sum += u64::from(x);
            sum > u64::from(u32::MAX)
        });
        assert_eq!(truth, want, "{name}: the case's own expectation");
        for (dev_name, device) in devices() {
            let offsets = exclusive_scan(ints(&values, &device)).unwrap();
            assert_eq!(scan_wrapped(offsets).unwrap(), want, "{name} on {dev_name}");
        }
    }
}

/// Guards bad arguments reaching the kernels.
#[test]
fn sort_and_scan_refuse_bad_arguments() {
    let device = Device::default();
    let k = ints(&[1, 2, 3], &device);
    let v = ints(&[1, 2], &device);
    assert_eq!(
        sort_pairs(k.clone(), v, 8).unwrap_err(),
        PrimitiveError::LengthMismatch { keys: 3, values: 2 }
    );
    assert_eq!(
        sort_pairs(k.clone(), k.clone(), 0).unwrap_err(),
        PrimitiveError::Bits(0)
    );
    assert_eq!(
        sort_pairs(k.clone(), k, 33).unwrap_err(),
        PrimitiveError::Bits(33)
    );
}
