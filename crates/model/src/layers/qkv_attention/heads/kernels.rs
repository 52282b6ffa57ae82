//! The packed projection's layout `[B, N, 3, H, d]` to and from the three head tensors
//! `[B, H, N, d]` of q, k and v, each as one kernel over every element (f32): the split a
//! plain move per element, reading the projection in order; the merge the inverse, writing
//! it in order. Burn's reshape of each permuted third costs one copy each (three a forward),
//! and its slice assignments three launches a backward.

use cubecl::prelude::*;

/// Which third of the projection its element `i` is in: 0 for q, 1 for k, 2 for v.
#[cube]
fn third(i: u32, heads: u32, head_dim: u32) -> u32 {
    (i / (head_dim * heads)) % 3
}

/// The flat index in a `[B, H, N, d]` head tensor of the projection's element `i`.
#[cube]
fn head_index(i: u32, tokens: u32, heads: u32, head_dim: u32) -> u32 {
    let e = i % head_dim;
    let h = (i / head_dim) % heads;
    let n = (i / (head_dim * heads * 3)) % tokens;
    let b = i / (head_dim * heads * 3 * tokens);
    ((b * heads + h) * tokens + n) * head_dim + e
}

/// `q`, `k`, `v` `[B, H, N, d]` from the contiguous projection `qkv` `[B, N, 3, H, d]` of
/// `len` elements.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn split_heads(
    qkv: &Tensor<f32>,
    q: &mut Tensor<f32>,
    k: &mut Tensor<f32>,
    v: &mut Tensor<f32>,
    tokens: u32,
    heads: u32,
    head_dim: u32,
    len: u32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let part = third(i, heads, head_dim);
    let at = head_index(i, tokens, heads, head_dim);
    let value = qkv[i as usize];
    if part == 0 {
        q[at as usize] = value;
    } else if part == 1 {
        k[at as usize] = value;
    } else {
        v[at as usize] = value;
    }
}

/// The projection's layout `[B, N, 3, H, d]` of `len` elements from the contiguous head
/// tensors `q`, `k`, `v` `[B, H, N, d]` (the gradients of the three thirds).
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn merge_heads(
    q: &Tensor<f32>,
    k: &Tensor<f32>,
    v: &Tensor<f32>,
    qkv: &mut Tensor<f32>,
    tokens: u32,
    heads: u32,
    head_dim: u32,
    len: u32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let part = third(i, heads, head_dim);
    let at = head_index(i, tokens, heads, head_dim);
    let value = if part == 0 {
        q[at as usize]
    } else if part == 1 {
        k[at as usize]
    } else {
        v[at as usize]
    };
    qkv[i as usize] = value;
}
