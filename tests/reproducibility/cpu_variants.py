#!/usr/bin/env python3
"""Runs hindsight as on other x86-64 CPUs and checks every result against the record.

What a CPU can choose for a program at run time, and how each is varied here:
  * Eigen's product blocking follows the cache sizes the CPU reports (cpuid). hindsight pins them
    (engine/dense_blocking.h); HINDSIGHT_EMULATE_CPU_CACHES hands Eigen other sizes first, as a CPU with
    those caches would, so the pin is what the variant tests. Without the pin, an emulated 48 KiB L1
    gives exactly the bits measured on an Intel Xeon with a 48 KiB L1 (docs/guides/reproducibility.md).
  * glibc picks FMA / AVX2 / AVX-512 variants of its math functions; GLIBC_TUNABLES=glibc.cpu.hwcaps=-X
    hides feature X from that choice (with HINDSIGHT_KERNELS=baseline for hindsight's own choice of
    kernels, which does not go through glibc).
  * hindsight's own kernels: HINDSIGHT_KERNELS=baseline or fma (the latter where the CPU has it).
  * the number of threads: --threads 1 to 4 (the elimination-tree partition follows it).
  * the BLAS: LD_LIBRARY_PATH at OpenBLAS's directory, for one process (when Debian's is installed).
Each variant runs the record's commands (tests/reproducibility/record.py: evaluate with gradients, a
3-iteration optimisation, and the Python module's psi1(x0) when its folder is given) and every quantity
must equal the record (tests/reproducibility/record.json), made on another machine: not merely this
machine's own unmodified run. A probe hashes glibc's and hindsight::dmath's results under each glibc
variant: the glibc hash moving shows the variant reaches another code path here (if it does not, the
output says the variant proves nothing on this CPU); the dmath hash must never move.

Usage: cpu_variants.py HINDSIGHT LIBM_PROBE WORKDIR [--python DIR] [--quick]
  --quick: the coarse 20 x 4 rod, compared with this machine's unmodified run (the record holds the
  default configuration only), for a fast local look.
Prints 'cpu variants: passed' and exits 0 when every result has the record's bits; else exits 1.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import record  # noqa: E402  (tests/reproducibility/record.py)

# L1 16/32/48/64 KiB with L2 and L3 sizes of real parts (and one each way past them).
CACHES = [
    (16 * 1024, 256 * 1024, 2 * 1024**2),
    (32 * 1024, 256 * 1024, 8 * 1024**2),
    (32 * 1024, 1024**2, 32 * 1024**2),
    (48 * 1024, 1280 * 1024, 24 * 1024**2),   # Ice Lake server class
    (48 * 1024, 2 * 1024**2, 105 * 1024**2),  # Sapphire Rapids class
    (64 * 1024, 512 * 1024, 16 * 1024**2),
    (64 * 1024, 4 * 1024**2, 256 * 1024**2),
]
VARIANTS = [(f"caches {c[0] // 1024} KiB L1, {c[1] // 1024} KiB L2, {c[2] // 1024**2} MiB L3",
             {"HINDSIGHT_EMULATE_CPU_CACHES": ",".join(map(str, c))}, ()) for c in CACHES]
VARIANTS += [(f"--threads {n}", {}, ("--threads", str(n))) for n in (1, 2, 3, 4)]
VARIANTS += [
    ("glibc without FMA, AVX2; baseline kernels",
     {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-FMA,-AVX2", "HINDSIGHT_KERNELS": "baseline"}, ()),
    ("glibc without AVX-512", {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F,-AVX512DQ"}, ()),
    ("glibc with SSE2 only; baseline kernels",
     {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX,-FMA,-AVX2,-AVX512F,-AVX512DQ,-SSE4_1,-SSE4_2",
      "HINDSIGHT_KERNELS": "baseline"}, ()),
    ("SSE2 only, 48 KiB L1, 3 threads",
     {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX,-FMA,-AVX2,-AVX512F,-AVX512DQ,-SSE4_1,-SSE4_2",
      "HINDSIGHT_KERNELS": "baseline", "HINDSIGHT_EMULATE_CPU_CACHES": "49152,2097152,110100480"},
     ("--threads", "3")),
]
OPENBLAS_DIR = "/usr/lib/x86_64-linux-gnu/openblas-pthread"
if os.path.isfile(os.path.join(OPENBLAS_DIR, "libblas.so.3")):
    VARIANTS.append(("OpenBLAS as the BLAS", {"LD_LIBRARY_PATH": OPENBLAS_DIR}, ()))

COARSE = ("--set", "rod.elementsAlongLength=20", "--set", "rod.elementsThroughHeight=4",
          "--set", "rod.modeCount=4")


def cpu_has_fma():
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((l.split(":", 1)[1].split() for l in f if l.startswith("flags")), [])
        return "fma" in flags and "avx2" in flags
    except OSError:
        return False


def blas_note(hindsight):
    """Whether hindsight loads a BLAS or LAPACK library at all (ldd's view of its dependencies)."""
    listing = subprocess.run(["ldd", hindsight], capture_output=True, text=True).stdout
    loaded = [line.split()[0] for line in listing.splitlines()
              if any(name in line for name in ("blas", "lapack", "cholmod", "umfpack"))]
    if loaded:
        return "hindsight loads " + ", ".join(loaded) + ": the variant exercises another BLAS"
    return "hindsight loads no BLAS or LAPACK; the variant guards against one entering the result path"


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("hindsight")
    parser.add_argument("probe")
    parser.add_argument("workdir")
    parser.add_argument("--python", help="the build's python/ folder: the module is checked in every variant")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    hindsight, probe, work = (os.path.abspath(a) for a in (args.hindsight, args.probe, args.workdir))
    variants = list(VARIANTS)
    if cpu_has_fma():
        variants.append(("HINDSIGHT_KERNELS=fma", {"HINDSIGHT_KERNELS": "fma"}, ()))
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    try:
        base_probe = record.run([probe], {}, work).split()
        if args.quick:
            reference = record.measure(hindsight, os.path.join(work, "reference"), flags=COARSE)
            print(f"reference (this machine, coarse rod): psi1(x0) = {reference['psi1(x0)']}")
        else:
            with open(record.DEFAULT_RECORD) as f:
                document = json.load(f)
            reference = document["quantities"]
            made = document["made_on"]
            print(f"reference: the record made on {made.get('cpu')} (caches {made.get('caches')}), "
                  f"psi1(x0) = {reference['psi1(x0)']}; this machine: {record.machine().get('cpu')} "
                  f"(caches {record.cache_sizes()})")
        failed = False
        for index, (name, env_extra, flags) in enumerate(variants):
            reach = ""
            if "GLIBC_TUNABLES" in env_extra:
                probe_out = record.run([probe], env_extra, work).split()
                if probe_out[3] != base_probe[3]:
                    print(f"{name}: hindsight::dmath's own results changed ({base_probe[3]} -> {probe_out[3]})")
                    failed = True
                reach = (" [reaches another libm code path here]" if probe_out[1] != base_probe[1]
                         else " [does not change libm here: proves nothing on this CPU]")
            elif "LD_LIBRARY_PATH" in env_extra:
                reach = f" [{blas_note(hindsight)}]"
            directory = os.path.join(work, f"variant{index}")
            measured = record.measure(hindsight, directory, env_extra,
                                      flags=(COARSE if args.quick else ()) + tuple(flags),
                                      python_dir=None if args.quick else args.python)
            shutil.rmtree(directory, ignore_errors=True)
            difference = record.first_difference(reference, measured)
            if difference:
                failed = True
                print(f"{name}{reach}: DIFFERS, first at {difference[0]}: "
                      f"expected {difference[1]}, got {difference[2]}")
            else:
                print(f"{name}{reach}: same bits as the reference")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if failed:
        print("cpu variants: FAILED")
        return 1
    print("cpu variants: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
