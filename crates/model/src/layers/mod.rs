//! Building blocks shared by the backbone and heads.

pub mod attention;
pub mod block;
pub mod cpu_attention;
pub mod cpu_conv;
pub mod cpu_gelu;
pub mod rope;

pub use attention::{Attention, QkNorm};
pub use block::{Block, BlockSpec, LayerScale, Mlp, BLOCK_NORM_EPS, DINO_NORM_EPS};
pub use rope::{frame_positions, RopeTables};
