#!/usr/bin/env python3
"""Writes a PyTorch-format Lightning checkpoint (.ckpt) from a safetensors file, using only the
Python standard library (no torch): a zip archive with `data.pkl` (pickle protocol 2 whose
tensors are `torch._utils._rebuild_tensor_v2` calls on persistent storages), one raw file per
storage, and `version`. This is the layout `torch.save` produces, so the checkpoint loader is
tested on a real-format file where torch itself cannot be installed.

usage: make_lightning_ckpt.py IN.safetensors OUT.ckpt [--strip PREFIX] [--prefix PREFIX] [--plain]
  --strip   only keep keys starting with PREFIX, removing it (e.g. "weights/")
  --prefix  prepend PREFIX to every kept key (e.g. "encoder.backbone.")
  --plain   write the bare state_dict (like VGGT-1B's model.pt) instead of {"state_dict": ...}
"""
import collections
import json
import pickle
import struct
import sys
import types
import zipfile

# Stand-ins that pickle under torch's names: pickle records module + qualname only.
torch_mod = types.ModuleType("torch")
utils_mod = types.ModuleType("torch._utils")


class FloatStorage:  # referenced as torch.FloatStorage
    pass


FloatStorage.__module__ = "torch"


def _rebuild_tensor_v2(*args):  # referenced as torch._utils._rebuild_tensor_v2
    raise RuntimeError("never called when writing")


_rebuild_tensor_v2.__module__ = "torch._utils"
torch_mod.FloatStorage = FloatStorage
utils_mod._rebuild_tensor_v2 = _rebuild_tensor_v2
sys.modules["torch"] = torch_mod
sys.modules["torch._utils"] = utils_mod


class Storage:
    def __init__(self, key, numel):
        self.key, self.numel = key, numel


class Tensor:
    def __init__(self, storage, shape):
        self.storage, self.shape = storage, shape

    def __reduce__(self):
        stride, acc = [], 1
        for d in reversed(self.shape):
            stride.insert(0, acc)
            acc *= d
        return (_rebuild_tensor_v2, (self.storage, 0, tuple(self.shape), tuple(stride), False, collections.OrderedDict()))


class Pickler(pickle.Pickler):
    def persistent_id(self, obj):
        if isinstance(obj, Storage):
            return ("storage", FloatStorage, obj.key, "cpu", obj.numel)
        return None


def read_safetensors(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    header.pop("__metadata__", None)
    for key, info in header.items():
        start, end = info["data_offsets"]
        yield key, info["dtype"], info["shape"], data[start:end]


def main(argv):
    args = list(argv)
    def opt(name):
        if name in args:
            i = args.index(name)
            value = args[i + 1]
            del args[i:i + 2]
            return value
        return None
    strip, prefix = opt("--strip") or "", opt("--prefix") or ""
    plain = "--plain" in args
    if plain:
        args.remove("--plain")
    src, dst = args
    state = collections.OrderedDict()
    blobs = []
    for key, dtype, shape, raw in read_safetensors(src):
        if not key.startswith(strip) or dtype != "F32":
            continue
        sid = str(len(blobs))
        blobs.append((sid, raw))
        state[prefix + key[len(strip):]] = Tensor(Storage(sid, len(raw) // 4), shape)
    obj = state if plain else {"state_dict": state, "epoch": 0, "global_step": 0}
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as z:
        import io
        buf = io.BytesIO()
        Pickler(buf, protocol=2).dump(obj)
        z.writestr("archive/data.pkl", buf.getvalue())
        for sid, raw in blobs:
            z.writestr(f"archive/data/{sid}", raw)
        z.writestr("archive/version", "3\n")
        z.writestr("archive/byteorder", "little")
    print(f"wrote {len(state)} tensors to {dst}")


if __name__ == "__main__":
    main(sys.argv[1:])
