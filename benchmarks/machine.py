"""The machine a benchmark ran on, printed beside its figures: a speed claim has to hold on AVX2-only and on
AVX-512 processors, and the same code can differ several-fold between them (docs/performance.md)."""

from __future__ import annotations

import os
import platform
from pathlib import Path

VECTOR_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl", "avx512_vnni", "avx512dq")
"""The x86 vector extensions that decide which kernels torch and the compiler can use."""


def _cpuinfo() -> tuple[str, set[str]]:
    model, flags = platform.processor() or platform.machine(), set()
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return model, flags
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "model name" and value.strip():
            model = value.strip()
        elif key.strip() == "flags":
            flags = set(value.split())
            break
    return model, flags


def cpu_summary() -> str:
    """One line: CPU model, logical cores available, the vector extensions present and torch's CPU capability."""
    model, flags = _cpuinfo()
    present = [flag for flag in VECTOR_FLAGS if flag in flags]
    try:
        import torch

        capability = torch.backends.cpu.get_cpu_capability()
    except (ImportError, AttributeError):
        capability = "unknown"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (
        f"cpu: {model}; {cores} cores; vector extensions: {' '.join(present) or 'none found'}; torch uses {capability}"
        f"; {_compiled_target()}"
    )


def _compiled_target() -> str:
    """The vector instruction set torch.compile's C++ kernels are generated for and the -march they are built
    with: ATEN_CPU_CAPABILITY=avx2 with TORCHINDUCTOR_CPP_MARCH=x86-64-v3 makes an AVX-512 machine build and run
    AVX2-only code, how docs/performance.md measures the other processor family on one machine."""
    try:
        from torch._inductor import config, cpu_vec_isa

        return f"compiled kernels: {cpu_vec_isa.pick_vec_isa() or 'scalar'}, -march={config.cpp.march or 'native'}"
    except (ImportError, AttributeError):
        return "compiled kernels: unknown"


def opencv_summary() -> str:
    """OpenCV's version and whether its AVX-512 code paths are in use. OpenCV 5 names them AVX512-SKX and
    AVX512-CLX in ``OPENCV_CPU_DISABLE`` (the underscore names of OpenCV 4 are reported unknown and ignored)."""
    try:
        import cv2
    except ImportError:
        return "opencv: not installed"
    # cv::CpuFeatures: CPU_AVX2 = 11, CPU_AVX_512F = 13, CPU_AVX512_SKX = 256, CPU_AVX512_CLX = 261.
    checks = {"avx2": 11, "avx512-skx": 256, "avx512-clx": 261}
    used = [name for name, feature in checks.items() if cv2.checkHardwareSupport(feature)]
    return f"opencv {cv2.__version__} dispatches to: {' '.join(used) or 'baseline only'}"
