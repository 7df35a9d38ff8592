#!/usr/bin/env python3
"""Emulates other x86-64 CPUs on this one and checks that hindsight's results keep their bits.

glibc chooses CPU-specific code paths (FMA, AVX2, AVX-512 variants of its math functions, string
and memory routines) at run time; GLIBC_TUNABLES=glibc.cpu.hwcaps=-X hides feature X from that
choice, so the same binary runs as on a CPU without it (with HINDSIGHT_KERNELS=baseline for
hindsight's own choice of kernels, which does not go through glibc). BLAS, were it on the result path, would be
chosen by Debian's alternatives; LD_LIBRARY_PATH pointing at OpenBLAS's directory selects it for
one process without touching the system. For each variant this runs

  hindsight evaluate --json --gradient g.h5      psi1(x0), psi2(x0), frequencies, every gradient
  hindsight optimize --iterations 3              history, designs and MMA state of a short run

and compares every number bit for bit with the unmodified run. The libm probe shows whether a
variant reaches a different glibc code path on this machine at all (if it does not, the variant
proves nothing here and the output says so); its hindsight::dmath hash must never move.

Usage: cpu_variants.py HINDSIGHT LIBM_PROBE WORKDIR [--quick]
  --quick: the coarse 20 x 4 rod instead of the paper's 200 x 12 (for a fast local check).
Prints 'cpu variants: passed' and exits 0 when every result is bitwise equal; else exits 1.
"""
import json
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

# hindsight's own run-time choice (the modal refinement's kernels built for the baseline and for AVX2 with
# FMA, problems/rod/compensated_kernels.h) reads the CPU itself, not glibc's tunables:
# HINDSIGHT_KERNELS=baseline makes it choose as a CPU without AVX2 and FMA would.
VARIANTS = [
    ("no FMA, no AVX2", {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-FMA,-AVX2", "HINDSIGHT_KERNELS": "baseline"}),
    ("no AVX-512", {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F,-AVX512DQ"}),
    ("only SSE2 (no AVX, FMA, AVX2, AVX-512)",
     {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX,-FMA,-AVX2,-AVX512F,-AVX512DQ,-SSE4_1,-SSE4_2",
      "HINDSIGHT_KERNELS": "baseline"}),
]
OPENBLAS_DIR = "/usr/lib/x86_64-linux-gnu/openblas-pthread"
if os.path.isfile(os.path.join(OPENBLAS_DIR, "libblas.so.3")):
    VARIANTS.append(("OpenBLAS as the BLAS", {"LD_LIBRARY_PATH": OPENBLAS_DIR}))

COARSE = ["--set", "rod.elementsAlongLength=20", "--set", "rod.elementsThroughHeight=4",
          "--set", "rod.modeCount=4"]


def run(command, env_extra, cwd):
    env = dict(os.environ)
    env.update(env_extra)
    result = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed ({result.returncode}):\n{result.stdout}\n{result.stderr}")
    return result.stdout


def datasets(path):
    """Every dataset of an HDF5 file as a NumPy array (seconds columns dropped: they are wall time)."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and "seconds" not in name:
                out[name] = np.asarray(obj[()])
        f.visititems(visit)
    return out


def outcome(hindsight, env_extra, directory, extra):
    os.makedirs(directory, exist_ok=True)
    gradient = os.path.join(directory, "g.h5")
    report = json.loads(run([hindsight, "evaluate", "--json", "--gradient", gradient, "--force"] + extra,
                            env_extra, directory))
    numbers = {k: report[k] for k in ("psi1", "psi2", "volume_fraction", "frequencies_hz") if k in report}
    run([hindsight, "optimize", "--iterations", "3", "--out", os.path.join(directory, "run"), "--force"]
        + extra, env_extra, directory)
    return numbers, datasets(gradient), datasets(os.path.join(directory, "run", "results.h5"))


def blas_note(hindsight):
    """Whether hindsight loads a BLAS or LAPACK library at all (ldd's view of its dependencies)."""
    listing = subprocess.run(["ldd", hindsight], capture_output=True, text=True).stdout
    loaded = [line.split()[0] for line in listing.splitlines()
              if any(name in line for name in ("blas", "lapack", "cholmod", "umfpack"))]
    if loaded:
        return "hindsight loads " + ", ".join(loaded) + ": the variant exercises another BLAS"
    return "hindsight loads no BLAS or LAPACK; the variant guards against one entering the result path"


def bits(array):
    a = np.ascontiguousarray(np.asarray(array))
    return a.shape, a.dtype.str, a.tobytes()


def compare(reference, candidate):
    """Names of the quantities whose bits differ, with the largest relative difference."""
    differences = []
    ref_numbers, ref_gradient, ref_run = reference
    numbers, gradient, run_data = candidate
    for key, value in ref_numbers.items():
        if json.dumps(value) != json.dumps(numbers.get(key)):
            differences.append(f"{key}: {ref_numbers[key]!r} vs {numbers.get(key)!r}")
    for label, ref, got in (("gradient file", ref_gradient, gradient), ("results file", ref_run, run_data)):
        for name, array in ref.items():
            if name not in got or bits(array) != bits(got[name]):
                other = got.get(name)
                detail = ""
                if other is not None and np.shape(other) == np.shape(array) and array.dtype.kind == "f":
                    scale = np.maximum(np.abs(array), np.finfo(float).tiny)
                    with np.errstate(invalid="ignore"):
                        detail = f" (largest relative difference {np.nanmax(np.abs(other - array) / scale):.2e})"
                differences.append(f"{label} /{name}{detail}")
    return differences


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    hindsight, probe, work = (os.path.abspath(a) for a in sys.argv[1:4])
    extra = COARSE if "--quick" in sys.argv[4:] else []
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    base_probe = run([probe], {}, work).split()
    reference = outcome(hindsight, {}, os.path.join(work, "reference"), extra)
    print(f"reference: psi1(x0) = {reference[0]['psi1']!r}, psi2(x0) = {reference[0]['psi2']!r}")
    failed = False
    for index, (name, env_extra) in enumerate(VARIANTS):
        probe_out = run([probe], env_extra, work).split()
        libm_moves = probe_out[1] != base_probe[1]
        if probe_out[3] != base_probe[3]:
            print(f"{name}: hindsight::dmath's own results changed ({base_probe[3]} -> {probe_out[3]})")
            failed = True
        if "LD_LIBRARY_PATH" in env_extra:
            reach = blas_note(hindsight)
        else:
            reach = ("reaches another libm code path here" if libm_moves
                     else "does not change libm here (proves nothing on this CPU)")
        differences = compare(reference, outcome(hindsight, env_extra, os.path.join(work, f"variant{index}"), extra))
        if differences:
            failed = True
            print(f"{name} [{reach}]: {len(differences)} results differ:")
            for line in differences:
                print("   ", line)
        else:
            print(f"{name} [{reach}]: bitwise equal")
    if failed:
        print("cpu variants: FAILED")
        return 1
    print("cpu variants: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
