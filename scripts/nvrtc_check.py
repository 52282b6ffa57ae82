#!/usr/bin/env python3
"""Compiles the project's CubeCL kernels through CubeCL's CUDA C++ route with NVIDIA's NVRTC
and assembles the result with ptxas, on a machine without a GPU: the route a `cuda-nvrtc` build
takes at run time (docs/PERFORMANCE.md, "Building for CUDA").

    ptx_check 90 DIR --cpp                       # the kernels' CUDA C++, one .cu each
    scripts/nvrtc_check.py DIR [--arch sm_90a]   # NVRTC, then ptxas, on each

NVRTC, the CUDA headers and ptxas come from NVIDIA's PyPI wheels (nvidia-cuda-nvrtc-cu12,
nvidia-cuda-runtime-cu12, nvidia-cuda-nvcc-cu12), downloaded into --wheels (default
runs/cuda-wheels) when not there. The options are the runtime's: the architecture, the
headers' folder, -lineinfo. Exit 1 when any kernel fails, with NVRTC's log.
"""
import argparse
import ctypes
import glob
import os
import subprocess
import sys
import zipfile

WHEELS = {
    "nvrtc": "nvidia-cuda-nvrtc-cu12",
    "runtime": "nvidia-cuda-runtime-cu12",
    "nvcc": "nvidia-cuda-nvcc-cu12",
}


def unpacked(wheels, key):
    """The folder of one wheel, unpacked (downloaded first when missing)."""
    package = WHEELS[key]
    folder = os.path.join(wheels, key)
    if os.path.isdir(folder):
        return folder
    os.makedirs(wheels, exist_ok=True)
    found = glob.glob(os.path.join(wheels, package.replace("-", "_") + "-*.whl"))
    if not found:
        subprocess.run(
            [sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", package,
             "-d", wheels],
            check=True,
        )
        found = glob.glob(os.path.join(wheels, package.replace("-", "_") + "-*.whl"))
    zipfile.ZipFile(found[0]).extractall(folder + ".tmp")
    os.rename(folder + ".tmp", folder)
    return folder


def nvrtc_library(folder):
    lib = glob.glob(os.path.join(folder, "nvidia/cuda_nvrtc/lib/libnvrtc.so.*"))
    if not lib:
        sys.exit(f"nvrtc_check: no libnvrtc.so.* under {folder}")
    # The builtins library sits beside it and is found by the same folder.
    return ctypes.CDLL(lib[0])


def check(nvrtc, call, what):
    """Raises with NVRTC's own message when `call` did not return NVRTC_SUCCESS."""
    if call != 0:
        nvrtc.nvrtcGetErrorString.restype = ctypes.c_char_p
        raise RuntimeError(f"{what}: {nvrtc.nvrtcGetErrorString(call).decode()}")


def compile_one(nvrtc, source, name, options):
    """(PTX, None) or (None, NVRTC's log) for one CUDA C++ source."""
    program = ctypes.c_void_p()
    check(nvrtc, nvrtc.nvrtcCreateProgram(ctypes.byref(program), source.encode(),
                                          name.encode(), 0, None, None), "create")
    opts = (ctypes.c_char_p * len(options))(*[o.encode() for o in options])
    try:
        if nvrtc.nvrtcCompileProgram(program, len(options), opts) != 0:
            size = ctypes.c_size_t()
            check(nvrtc, nvrtc.nvrtcGetProgramLogSize(program, ctypes.byref(size)), "log size")
            log = ctypes.create_string_buffer(size.value)
            check(nvrtc, nvrtc.nvrtcGetProgramLog(program, log), "log")
            return None, log.value.decode(errors="replace")
        size = ctypes.c_size_t()
        check(nvrtc, nvrtc.nvrtcGetPTXSize(program, ctypes.byref(size)), "PTX size")
        ptx = ctypes.create_string_buffer(size.value)
        check(nvrtc, nvrtc.nvrtcGetPTX(program, ptx), "PTX")
        return ptx.value.decode(), None
    finally:
        nvrtc.nvrtcDestroyProgram(ctypes.byref(program))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dir", help="the .cu files of `ptx_check SM DIR --cpp`")
    parser.add_argument("--arch", default="sm_90a",
                        help="NVRTC's --gpu-architecture (the runtime's: sm_90a on Hopper)")
    parser.add_argument("--wheels", default="runs/cuda-wheels")
    args = parser.parse_args()
    sources = sorted(glob.glob(os.path.join(args.dir, "*.cu")))
    if not sources:
        sys.exit(f"nvrtc_check: no .cu files in {args.dir} (run ptx_check with --cpp first)")
    nvrtc = nvrtc_library(unpacked(args.wheels, "nvrtc"))
    include = os.path.join(unpacked(args.wheels, "runtime"), "nvidia/cuda_runtime/include")
    ptxas = os.path.join(unpacked(args.wheels, "nvcc"), "nvidia/cuda_nvcc/bin/ptxas")
    os.chmod(ptxas, 0o755)
    options = [f"--gpu-architecture={args.arch}", f"--include-path={include}", "-lineinfo"]
    failed = 0
    for path in sources:
        name = os.path.basename(path)[:-3]
        with open(path) as f:
            ptx, log = compile_one(nvrtc, f.read(), name, options)
        if ptx is None:
            print(f"FAILED  {name}: NVRTC:\n{log}")
            failed += 1
            continue
        target = next((l.split()[1] for l in ptx.splitlines() if l.startswith(".target")),
                      args.arch)
        out = path[:-3] + ".nvrtc.ptx"
        with open(out, "w") as f:
            f.write(ptx)
        run = subprocess.run([ptxas, f"-arch={target}", "-v", out, "-o", os.devnull],
                             capture_output=True, text=True)
        if run.returncode != 0:
            print(f"FAILED  {name}: ptxas:\n{run.stderr}")
            failed += 1
            continue
        regs = [l.split("Used ")[1].split(",")[0] for l in run.stderr.splitlines()
                if "Used " in l]
        print(f"ok      {name}: {len(ptx)} bytes of PTX ({target}), {', '.join(regs)}")
    print(f"{args.arch}, CUDA C++ through NVRTC and ptxas: {failed} of {len(sources)} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
