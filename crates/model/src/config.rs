//! The model configuration (TOML section `[model]`): every dimension of the network, with the
//! `paper` preset (VGGT-1B widths, T_c = T_f = 2) and the `tiny` preset of the golden fixtures.

use serde::{Deserialize, Serialize};

/// The DINOv2 ViT used as patch embedding.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DinoConfig {
    pub embed_dim: usize,
    pub depth: usize,
    pub num_heads: usize,
    /// Pretraining image size: the stored pos-embed grid is `img_size / patch_size` squared.
    pub img_size: usize,
}

/// Widths of the three DPT heads (depth, Gaussians, motion).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DptConfig {
    pub features: usize,
    pub out_channels: [usize; 4],
}

/// Every dimension of Envision4D.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// Aggregator width C (heads and the future-pose module run at 2C).
    pub embed_dim: usize,
    /// Number of frame/global block pairs.
    pub depth: usize,
    pub num_heads: usize,
    pub patch_size: usize,
    pub num_register_tokens: usize,
    /// Global-block indices after which a temporal block runs; also the DPT taps.
    pub temporal_layers: [usize; 4],
    pub dino: DinoConfig,
    pub dpt: DptConfig,
    /// Heads of the camera-head trunk (at width 2C).
    pub camera_heads: usize,
    /// Blocks in the shared future-pose stack (at width 2C, `extra_blocks`).
    pub future_blocks: usize,
    /// Passes of the future-pose stack.
    pub future_iterations: usize,
    /// Heads of the future-pose blocks.
    pub future_heads: usize,
    pub context_frames: usize,
    pub future_frames: usize,
    /// Input image size `[H, W]`; both multiples of `patch_size`.
    pub image_size: [usize; 2],
    pub gaussian_scale_min: f64,
    pub gaussian_scale_max: f64,
    /// How the motion head turns tokens into displacements (ablation table: "CML").
    /// Defaulted, and left out of the serialised form when it is the paper's, so configs and
    /// checkpoint metadata written before this switch existed still parse and mean the paper
    /// model, and paper-model metadata stays readable by older builds.
    #[serde(default, skip_serializing_if = "MotionModel::is_paper")]
    pub motion_model: MotionModel,
    /// Where the temporal blocks sit (ablation table: "In-layer" vs "Post-layer TAttn").
    /// Defaulted and skipped when it is the paper's, for the same reason as `motion_model`.
    #[serde(default, skip_serializing_if = "TemporalPlacement::is_paper")]
    pub temporal_attention: TemporalPlacement,
}

/// Components of one 3D displacement or velocity.
pub const DISPLACEMENT_DIM: usize = 3;
/// Velocities per pixel in the linear-velocity baseline: one forward, one backward in time.
pub const VELOCITY_DIRECTIONS: usize = 2;

/// The motion model of the ablation table (paper §4.3, `tab:ablation`, column "CML").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionModel {
    /// Conditioned motion lifting (paper §3.3): the motion tokens of source i are modulated by
    /// the refined time token of every other timestamp j, and the motion head predicts one
    /// displacement per (i, j) pair.
    #[default]
    Lifting,
    /// The ablation baseline ("linear bidirectional velocity estimation", paper §4.3): the
    /// motion head predicts, once per context frame, a forward and a backward velocity per
    /// pixel, and a Gaussian of frame i reaches timestamp j by `v·(j − i)` (see
    /// [`crate::motion::linear_displacements`]).
    LinearVelocity,
    /// No motion, trained that way (the control of the motion benchmark): every displacement
    /// is zero and the motion head never runs. The head is still built with the lifting
    /// layout, so checkpoints of every variant share one set of keys.
    Off,
}

impl MotionModel {
    pub fn is_paper(&self) -> bool {
        *self == MotionModel::Lifting
    }

    /// Output channels of the motion DPT head: one displacement per lifted (i, j) map, or
    /// `[v_fwd | v_bwd]` per context frame.
    pub fn head_channels(self) -> usize {
        match self {
            MotionModel::Lifting | MotionModel::Off => DISPLACEMENT_DIM,
            MotionModel::LinearVelocity => VELOCITY_DIRECTIONS * DISPLACEMENT_DIM,
        }
    }
}

/// Where the four temporal blocks run (paper §4.3, `tab:ablation`: "In-layer" or
/// "Post-layer TAttn").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TemporalPlacement {
    /// Paper §3.2: after the global blocks of `temporal_layers`; each output continues into
    /// the next frozen layer, so the DPT taps and camera tokens see the temporal cues.
    #[default]
    InLayer,
    /// The ablation: the frozen layers run untouched (taps and camera tokens are plain VGGT)
    /// and the same four blocks are stacked after the last layer, feeding only the motion
    /// tokens (see [`crate::aggregator`]).
    PostLayer,
    /// The ablation without temporal attention (Tab. 3, rows without TAttn): no temporal
    /// blocks at all (none are built); the motion tokens take the global output at each
    /// temporal layer in place of a temporal block's, `time_list[t] = cat(G_ℓt, G_ℓt)`, so
    /// the motion head keeps its input and only the temporal attention is removed.
    None,
}

impl TemporalPlacement {
    pub fn is_paper(&self) -> bool {
        *self == TemporalPlacement::InLayer
    }
}

/// Constants of the architecture that no released checkpoint varies.
pub const MLP_RATIO: usize = 4;
pub const CAMERA_TRUNK_DEPTH: usize = 4;
pub const CAMERA_ITERATIONS: usize = 4;
/// Width of the sinusoidal time embedding fed to `time_embedding`.
pub const TIME_SINUSOID_DIM: usize = 256;
/// Pose encoding `absT_quaR_FoV`: translation 3, quaternion (x, y, z, w) 4, FoV (h, w) 2.
pub const POSE_ENC_DIM: usize = crate::pose::POSE_ENCODING_DIM;
/// Raw Gaussian channels: opacity 1, scale 3, rotation 4, colour 3.
pub const GAUSSIAN_DIM: usize = 11;

impl ModelConfig {
    /// The released model: VGGT-1B widths, 2 context and 2 future frames at 350x518.
    pub fn paper() -> Self {
        ModelConfig {
            embed_dim: 1024,
            depth: 24,
            num_heads: 16,
            patch_size: 14,
            num_register_tokens: 4,
            temporal_layers: [4, 11, 17, 23],
            dino: DinoConfig {
                embed_dim: 1024,
                depth: 24,
                num_heads: 16,
                img_size: 518,
            },
            dpt: DptConfig {
                features: 256,
                out_channels: [256, 512, 1024, 1024],
            },
            camera_heads: 16,
            future_blocks: 2,
            future_iterations: 4,
            future_heads: 16,
            context_frames: 2,
            future_frames: 2,
            image_size: [350, 518],
            gaussian_scale_min: 0.5,
            gaussian_scale_max: 15.0,
            motion_model: MotionModel::Lifting,
            temporal_attention: TemporalPlacement::InLayer,
        }
    }

    /// The widths of `../shared/fixtures/envision4d_tiny.safetensors` (56x84 input).
    pub fn tiny() -> Self {
        ModelConfig {
            embed_dim: 64,
            num_heads: 4,
            dino: DinoConfig {
                embed_dim: 64,
                depth: 2,
                num_heads: 4,
                img_size: 518,
            },
            dpt: DptConfig {
                features: 32,
                out_channels: [16, 32, 64, 64],
            },
            image_size: [56, 84],
            ..Self::paper()
        }
    }

    /// A preset by name (`paper` or `tiny`).
    pub fn preset(name: &str) -> Result<Self, ConfigError> {
        match name {
            "paper" => Ok(Self::paper()),
            "tiny" => Ok(Self::tiny()),
            other => Err(ConfigError(format!(
                "unknown model preset {other:?}; use \"paper\" or \"tiny\""
            ))),
        }
    }

    pub fn num_frames(&self) -> usize {
        self.context_frames + self.future_frames
    }

    /// Patch grid `(rows, cols)`.
    pub fn patch_grid(&self) -> (usize, usize) {
        (
            self.image_size[0] / self.patch_size,
            self.image_size[1] / self.patch_size,
        )
    }

    /// Tokens per frame: camera + registers + patches.
    pub fn tokens_per_frame(&self) -> usize {
        let (h, w) = self.patch_grid();
        1 + self.num_register_tokens + h * w
    }

    /// Rejects impossible configurations with a message naming the field and the values.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |m: String| Err(ConfigError(m));
        let divides = |name: &str, dim: usize, heads: usize| -> Result<(), ConfigError> {
            if heads == 0 || !dim.is_multiple_of(heads) {
                return Err(ConfigError(format!(
                    "{name}: {heads} heads do not divide width {dim}"
                )));
            }
            Ok(())
        };
        divides("num_heads", self.embed_dim, self.num_heads)?;
        divides("dino.num_heads", self.dino.embed_dim, self.dino.num_heads)?;
        divides("camera_heads", 2 * self.embed_dim, self.camera_heads)?;
        divides("future_heads", 2 * self.embed_dim, self.future_heads)?;
        if self.dino.embed_dim != self.embed_dim {
            return err(format!(
                "dino.embed_dim ({}) must equal embed_dim ({})",
                self.dino.embed_dim, self.embed_dim
            ));
        }
        // 2D RoPE splits each head in a y half and an x half, each rotated in pairs.
        if !(self.embed_dim / self.num_heads).is_multiple_of(4) {
            return err(format!(
                "head dim {} (embed_dim / num_heads) must be a multiple of 4 for 2D RoPE",
                self.embed_dim / self.num_heads
            ));
        }
        if self.patch_size == 0 {
            return err("patch_size must be > 0".into());
        }
        for (axis, v) in ["height", "width"].iter().zip(self.image_size) {
            if v == 0 || v % self.patch_size != 0 {
                return err(format!(
                    "image_size {axis} {v} is not a positive multiple of patch_size {}",
                    self.patch_size
                ));
            }
        }
        if !self.dino.img_size.is_multiple_of(self.patch_size) {
            return err(format!(
                "dino.img_size {} is not a multiple of patch_size {}",
                self.dino.img_size, self.patch_size
            ));
        }
        let mut prev = None;
        for &l in &self.temporal_layers {
            if l >= self.depth {
                return err(format!(
                    "temporal_layers entry {l} is not below depth {}",
                    self.depth
                ));
            }
            if prev.is_some_and(|p| l <= p) {
                return err(format!(
                    "temporal_layers {:?} must be strictly increasing",
                    self.temporal_layers
                ));
            }
            prev = Some(l);
        }
        if self.context_frames < 2 {
            return err(format!("context_frames must be >= 2 (self-exclusive rendering needs another frame), got {}", self.context_frames));
        }
        if self.future_frames == 0 || self.future_iterations == 0 || self.future_blocks == 0 {
            return err("future_frames, future_blocks and future_iterations must be >= 1".into());
        }
        if self.dpt.features == 0 || self.dpt.out_channels.contains(&0) {
            return err(format!(
                "dpt widths must be > 0, got features {} out_channels {:?}",
                self.dpt.features, self.dpt.out_channels
            ));
        }
        if !(self.gaussian_scale_min > 0.0 && self.gaussian_scale_max > self.gaussian_scale_min) {
            return err(format!(
                "need 0 < gaussian_scale_min < gaussian_scale_max, got {} and {}",
                self.gaussian_scale_min, self.gaussian_scale_max
            ));
        }
        // Every (motion_model, temporal_attention) pair is a network the ablation table
        // trains: both motion models read the four `time_list` maps, which both placements
        // produce, so no combination is refused here.
        Ok(())
    }
}

/// An impossible or unknown model configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("model config: {0}")]
pub struct ConfigError(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the presets themselves: both must validate.
    #[test]
    fn presets_validate() {
        ModelConfig::paper().validate().unwrap();
        ModelConfig::tiny().validate().unwrap();
        assert_eq!(ModelConfig::paper().tokens_per_frame(), 930);
        assert_eq!(ModelConfig::tiny().tokens_per_frame(), 29);
    }

    /// Guards the error messages of impossible configs: each names the field and values.
    #[test]
    fn impossible_configs_are_rejected_with_names() {
        let bad = |f: fn(&mut ModelConfig), needle: &str| {
            let mut c = ModelConfig::tiny();
            f(&mut c);
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(needle), "{e} should mention {needle}");
        };
        bad(|c| c.num_heads = 5, "num_heads");
        bad(|c| c.image_size = [57, 84], "height 57");
        bad(|c| c.temporal_layers = [4, 11, 30, 23], "temporal_layers");
        bad(|c| c.context_frames = 1, "context_frames");
        bad(|c| c.camera_heads = 7, "camera_heads");
        bad(|c| c.gaussian_scale_min = 0.0, "gaussian_scale_min");
        assert!(ModelConfig::preset("huge")
            .unwrap_err()
            .to_string()
            .contains("huge"));
    }

    /// Guards `deny_unknown_fields`: a typo in a TOML/JSON model section is an error naming it.
    #[test]
    fn unknown_field_is_rejected() {
        let mut v = serde_json::to_value(ModelConfig::tiny()).unwrap();
        v["embed_dimm"] = serde_json::json!(3);
        let e = serde_json::from_value::<ModelConfig>(v)
            .unwrap_err()
            .to_string();
        assert!(e.contains("embed_dimm"), "{e}");
    }
}
