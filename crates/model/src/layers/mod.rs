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

/// Whether the CPU inference kernels (`cpu_attention`, `cpu_conv`, `cpu_gelu`, the bilinear
/// resize) may run on `device`: the CPU backend *without* autodiff. They compute on host
/// buffers, so on an autodiff device they would cut the graph. (`Device`'s equality ignores
/// the autodiff wrapper, hence the explicit check.)
pub fn cpu_inference(device: &burn::tensor::Device) -> bool {
    !device.is_autodiff() && *device == burn::tensor::Device::flex()
}

#[cfg(test)]
mod tests {
    use burn::nn::conv::Conv2dConfig;
    use burn::nn::PaddingConfig2d;
    use burn::tensor::{Device, Distribution, Tensor};

    /// Guards the dispatch of the CPU inference kernels: on an autodiff CPU device they must
    /// not run (they compute on host buffers and would cut the graph; `Device`'s equality
    /// ignores the autodiff wrapper). Each dispatcher's input gets a non-zero gradient.
    #[test]
    fn cpu_kernels_never_cut_an_autodiff_graph() {
        let device = Device::flex().autodiff();
        assert!(!super::cpu_inference(&device));
        assert!(super::cpu_inference(&Device::flex()));
        let x = || {
            Tensor::<4>::random([1, 4, 6, 8], Distribution::Uniform(-1.0, 1.0), &device)
                .require_grad()
        };
        let conv = Conv2dConfig::new([4, 4], [3, 3])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(&device);
        let attention = super::Attention::new(8, 2, super::QkNorm::On, &device);
        let ops: [(&str, Box<dyn Fn(Tensor<4>) -> Tensor<4>>); 4] = [
            ("conv", Box::new(|t| super::cpu_conv::conv2d(&conv, t))),
            ("gelu", Box::new(super::cpu_gelu::gelu)),
            (
                "bilinear",
                Box::new(|t| crate::resample::bilinear_align_corners(t, 11, 13)),
            ),
            (
                "attention",
                Box::new(|t: Tensor<4>| {
                    attention
                        .forward(t.reshape([1, 24, 8]), None)
                        .reshape([1, 4, 6, 8])
                }),
            ),
        ];
        for (name, op) in ops {
            let input = x();
            let grads = (op(input.clone()) * 1.7).sum().backward();
            let g = input
                .grad(&grads)
                .unwrap_or_else(|| panic!("{name}: no gradient reached the input"));
            let norm = g
                .abs()
                .sum()
                .into_data()
                .convert::<f32>()
                .try_into_vec::<f32>()
                .unwrap()[0];
            assert!(norm > 0.0, "{name}: zero gradient");
        }
    }
}
