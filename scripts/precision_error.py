"""Worst relative error (max |diff| / max |ref|) of each output `envision4d render
--export-predictions` wrote, against the official f32 reference in a fixture
(`expected/<key>`). Pure Python. For a reduced-precision run on a GPU backend, e.g.

    F=$FIXTURES/envision4d_tiny.safetensors   # the official golden fixture
    envision4d render --weights $F --weights-prefix weights/ --model-config tiny \
        --input-tensor $F:input/images --export-predictions f16.safetensors \
        --backend wgpu --precision f16
    python3 scripts/precision_error.py f16.safetensors $F
"""
import json
import struct
import sys

KEYS = ["pose_enc", "depth", "depth_conf", "gaussians", "motion_enc",
        "adapter/means", "adapter/motions"]


def load(path):
    """The F32 tensors of a safetensors file, flattened."""
    b = open(path, "rb").read()
    n = struct.unpack("<Q", b[:8])[0]
    header = json.loads(b[8:8 + n])
    out = {}
    for key, v in header.items():
        if key == "__metadata__" or v["dtype"] != "F32":
            continue
        s, e = v["data_offsets"]
        out[key] = struct.unpack(f"<{(e - s) // 4}f", b[8 + n + s:8 + n + e])
    return out


def main(got_path, ref_path):
    got, ref = load(got_path), load(ref_path)
    for key in KEYS:
        g, w = got[key], ref["expected/" + key]
        scale = max(abs(x) for x in w)
        worst = max(abs(a - b) for a, b in zip(g, w))
        print(f"{key}: max|diff|/max|ref| = {worst / scale:.2e}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
