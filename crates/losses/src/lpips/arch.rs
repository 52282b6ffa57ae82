//! The two LPIPS backbones as tables: torchvision `vgg16().features` and
//! `alexnet().features`, cut into the five slices the `lpips` package taps.
//!
//! Key names are the package's: `net.slice{s}.{i}.weight` where `i` is the torchvision
//! `features` index of the conv, and `lin{k}.model.1.weight` for the learned 1×1 layers.

/// Which backbone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LpipsNet {
    /// VGG16 (the paper's evaluation, the release's `lpips.LPIPS(net="vgg")`).
    Vgg,
    /// AlexNet (the `lpips` package's default network).
    Alex,
}

impl LpipsNet {
    /// The package's `net=` string.
    pub fn name(self) -> &'static str {
        match self {
            LpipsNet::Vgg => "vgg",
            LpipsNet::Alex => "alex",
        }
    }

    /// Parse the package's `net=` string.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "vgg" | "vgg16" => Some(LpipsNet::Vgg),
            "alex" | "alexnet" => Some(LpipsNet::Alex),
            _ => None,
        }
    }

    /// The five slices of the backbone (each tapped after its last ReLU).
    pub(crate) fn slices(self) -> &'static [Slice; LPIPS_LAYERS] {
        match self {
            LpipsNet::Vgg => &VGG16,
            LpipsNet::Alex => &ALEXNET,
        }
    }

    /// Channels of the five tapped features (= input channels of the five lin layers).
    pub fn channels(self) -> [usize; LPIPS_LAYERS] {
        self.slices().map(|s| s.convs[s.convs.len() - 1].out_ch)
    }
}

/// Number of tapped layers (and lin layers) in both networks.
pub const LPIPS_LAYERS: usize = 5;

/// A max-pool window (no padding, floor mode, as torchvision's `MaxPool2d`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Pool {
    pub kernel: usize,
    pub stride: usize,
}

/// A conv layer followed by ReLU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ConvSpec {
    /// torchvision `features` index, part of the key name.
    pub index: usize,
    pub in_ch: usize,
    pub out_ch: usize,
    pub kernel: usize,
    pub stride: usize,
    pub padding: usize,
}

/// One LPIPS slice: an optional pool, then conv+ReLU layers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Slice {
    pub pool: Option<Pool>,
    pub convs: &'static [ConvSpec],
}

const fn conv3(index: usize, in_ch: usize, out_ch: usize) -> ConvSpec {
    ConvSpec {
        index,
        in_ch,
        out_ch,
        kernel: 3,
        stride: 1,
        padding: 1,
    }
}

/// VGG16 pools 2×2/2 before slices 2..5 (features indices 4, 9, 16, 23).
const VGG_POOL: Option<Pool> = Some(Pool {
    kernel: 2,
    stride: 2,
});

static VGG16: [Slice; LPIPS_LAYERS] = [
    Slice {
        pool: None,
        convs: &[conv3(0, 3, 64), conv3(2, 64, 64)],
    },
    Slice {
        pool: VGG_POOL,
        convs: &[conv3(5, 64, 128), conv3(7, 128, 128)],
    },
    Slice {
        pool: VGG_POOL,
        convs: &[
            conv3(10, 128, 256),
            conv3(12, 256, 256),
            conv3(14, 256, 256),
        ],
    },
    Slice {
        pool: VGG_POOL,
        convs: &[
            conv3(17, 256, 512),
            conv3(19, 512, 512),
            conv3(21, 512, 512),
        ],
    },
    Slice {
        pool: VGG_POOL,
        convs: &[
            conv3(24, 512, 512),
            conv3(26, 512, 512),
            conv3(28, 512, 512),
        ],
    },
];

/// AlexNet pools 3×3/2 before slices 2 and 3 (features indices 2, 5).
const ALEX_POOL: Option<Pool> = Some(Pool {
    kernel: 3,
    stride: 2,
});

static ALEXNET: [Slice; LPIPS_LAYERS] = [
    Slice {
        pool: None,
        convs: &[ConvSpec {
            index: 0,
            in_ch: 3,
            out_ch: 64,
            kernel: 11,
            stride: 4,
            padding: 2,
        }],
    },
    Slice {
        pool: ALEX_POOL,
        convs: &[ConvSpec {
            index: 3,
            in_ch: 64,
            out_ch: 192,
            kernel: 5,
            stride: 1,
            padding: 2,
        }],
    },
    Slice {
        pool: ALEX_POOL,
        convs: &[conv3(6, 192, 384)],
    },
    Slice {
        pool: None,
        convs: &[conv3(8, 384, 256)],
    },
    Slice {
        pool: None,
        convs: &[conv3(10, 256, 256)],
    },
];

/// Key of a conv weight or bias (`part` = "weight" | "bias") in slice `s` (0-based).
pub(crate) fn conv_key(slice: usize, conv: &ConvSpec, part: &str) -> String {
    format!("net.slice{}.{}.{part}", slice + 1, conv.index)
}

/// Key of lin layer `k` (0-based).
pub fn lin_key(k: usize) -> String {
    format!("lin{k}.model.1.weight")
}

/// Spatial sizes `(h, w)` of the five tapped features for an `h × w` input, or `None` when
/// some layer would be empty.
pub(crate) fn feature_sizes(net: LpipsNet, h: usize, w: usize) -> Option<[(usize, usize); 5]> {
    let mut size = (h, w);
    let mut out = [(0, 0); LPIPS_LAYERS];
    let shrink =
        |n: usize, k: usize, s: usize, p: usize| (n + 2 * p).checked_sub(k).map(|r| r / s + 1);
    for (slot, slice) in out.iter_mut().zip(net.slices()) {
        if let Some(p) = slice.pool {
            size = (
                shrink(size.0, p.kernel, p.stride, 0)?,
                shrink(size.1, p.kernel, p.stride, 0)?,
            );
        }
        for c in slice.convs {
            size = (
                shrink(size.0, c.kernel, c.stride, c.padding)?,
                shrink(size.1, c.kernel, c.stride, c.padding)?,
            );
        }
        if size.0 == 0 || size.1 == 0 {
            return None;
        }
        *slot = size;
    }
    Some(out)
}
