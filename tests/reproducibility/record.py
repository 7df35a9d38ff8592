#!/usr/bin/env python3
"""The record: the bits of hindsight's default configuration, kept in the repository
(tests/reproducibility/record.json), against which every machine's run is checked.

A machine compared with itself cannot show that its results are another machine's: the cause of a
difference (a CPU feature, a cache size, a library version) is the same in both runs. The record was
made on one machine and names it; `check` runs the same commands here and compares every quantity bit
for bit, so whatever machine runs the test suite checks the claim "the same bits on every x86-64 CPU".

    record.py check HINDSIGHT WORKDIR [--record FILE] [--python DIR]
    record.py write HINDSIGHT WORKDIR [--record FILE]      (re-baseline; say why in the CHANGELOG)
    record.py machine                                      (this machine's description, as JSON)

The quantities, in the order they are compared (the first that differs is named):
  hindsight evaluate --json --gradient g.h5      psi1(x0), psi2(x0), the ten frequencies, and a
                                                  SHA-256 of each gradient (dpsi1/dx, dpsi2/dx, dV/dx)
  the same with the solid member (SOLID_FLAGS)    its psi1, psi2, frequencies and gradients' SHA-256
                                                  (added later, on the machine named in solid_made_on)
  hindsight optimize --iterations 3              psi1 of each record, and a SHA-256 of every history
                                                  column, of the designs and of the optimizer's state
With --python DIR (the build's python/ folder) the Python module's psi1(x0) is compared too: the module
carries its own copy of Eigen's settings (engine/dense_blocking.h). `check` exits 0 and prints
'record: same bits' or exits 1 naming the first quantity that differs and both values.
"""
import argparse
import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_RECORD = os.path.join(HERE, "record.json")
# Wall-clock columns are the machine's own, not results.
TIMING_COLUMNS = ("evaluation_seconds", "mma_seconds", "total_seconds")
# The solid member's coarse case (docs/tutorials/rod_as_solid.md), evaluated with gradients.
SOLID_FLAGS = ("--set", "rod.elementsAlongLength=40", "--set", "rod.elementsThroughHeight=4",
               "--set", "rod.elementsThroughThickness=2", "--set", "rod.midPlaneSymmetry=true")


def cache_sizes():
    """The data and unified caches of cpu0 as the kernel reports them (sysfs), e.g. {'L1d': '48K'}."""
    sizes = {}
    base = "/sys/devices/system/cpu/cpu0/cache"
    for entry in sorted(os.listdir(base)) if os.path.isdir(base) else []:
        def read(name):
            try:
                with open(os.path.join(base, entry, name)) as f:
                    return f.read().strip()
            except OSError:
                return ""
        kind = read("type")
        if kind in ("Data", "Unified"):
            sizes[f"L{read('level')}{'d' if kind == 'Data' else ''}"] = read("size")
    return sizes


def machine():
    info = {"platform": platform.platform(), "glibc": " ".join(platform.libc_ver()), "cores": os.cpu_count()}
    try:
        with open("/proc/cpuinfo") as f:
            text = f.read()
        fields = dict(line.split(":", 1) for line in text.splitlines() if ":" in line)
        fields = {k.strip(): v.strip() for k, v in fields.items()}
        info["cpu"] = fields.get("model name", "?")
        info["cpu_family_model"] = f"{fields.get('cpu family', '?')}/{fields.get('model', '?')}"
        flags = fields.get("flags", "").split()
        info["features"] = " ".join(f for f in ("sse4_2", "avx", "fma", "avx2", "avx512f") if f in flags)
    except OSError:
        pass
    info["caches"] = cache_sizes()
    return info


def run(command, env_extra, cwd):
    env = dict(os.environ)
    env.update(env_extra)
    result = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed ({result.returncode}):\n{result.stdout}\n{result.stderr}")
    return result.stdout


def digest(array):
    a = np.ascontiguousarray(np.asarray(array))
    return hashlib.sha256(a.dtype.str.encode() + str(a.shape).encode() + a.tobytes()).hexdigest()


def measure(hindsight, directory, env_extra=None, flags=(), python_dir=None):
    """Every recorded quantity of this machine's run, as {name: text}, in comparison order. `flags` are
    added to both commands (e.g. --threads 3); the record holds for any of them."""
    env_extra = env_extra or {}
    os.makedirs(directory, exist_ok=True)
    out = {}

    def evaluate(prefix, evaluate_flags):
        """`hindsight evaluate --json --gradient`: psi1, psi2, the frequencies and each gradient's SHA-256,
        named with `prefix`."""
        gradient = os.path.join(directory, "g.h5")
        report = json.loads(run([hindsight, "evaluate", "--json", "--gradient", gradient, "--force",
                                 *evaluate_flags], env_extra, directory))
        out[f"{prefix}psi1(x0)"] = repr(report["psi1"])
        out[f"{prefix}psi2(x0)"] = repr(report["psi2"])
        if not prefix:  # the plate's first frequency, named on its own since the record began
            out["first frequency (Hz)"] = repr(report["frequencies_hz"][0])
        out[f"{prefix}frequencies (Hz)"] = repr(report["frequencies_hz"])
        with h5py.File(gradient, "r") as f:
            for name in ("dpsi1_dx", "dpsi2_dx", "dvolume_dx"):
                out[f"{prefix}sha256 {name}"] = digest(f[name][()])

    evaluate("", flags)
    # The solid member (40 x 4 x 2, mid-plane symmetry) has code of its own on the way to its bits: the
    # supernodal factor with its blocked products, the 3-D invariants, the hexahedra's double-double
    # kernels. Its flags come last, so that they win over any --set in `flags`.
    evaluate("solid ", (*flags, *SOLID_FLAGS))
    results = os.path.join(directory, "run")
    run([hindsight, "optimize", "--iterations", "3", "--out", results, "--force", *flags], env_extra, directory)
    with h5py.File(os.path.join(results, "results.h5"), "r") as f:
        out["optimization psi1 per record"] = repr([float(v) for v in f["history/psi1"][()]])
        for name in sorted(f["history"]):
            if name not in TIMING_COLUMNS:
                out[f"sha256 history/{name}"] = digest(f["history"][name][()])
        out["sha256 designs"] = digest(f["designs"][()])
        for group in ("state", "final"):
            for name in sorted(f[group]):
                out[f"sha256 {group}/{name}"] = digest(f[group][name][()])
    if python_dir:
        code = ("import json, hindsight, hindsight._hindsight as h; r = hindsight.PistonRod(); "
                "e = r.evaluate(gradient=False); print(json.dumps({'psi1': repr(e['psi1']), "
                "'blocking': h._dense_blocking()}))")
        env = {"PYTHONPATH": os.path.abspath(python_dir), "PYTHONDONTWRITEBYTECODE": "1", **env_extra}
        reply = json.loads(run(["/usr/bin/python3", "-c", code], env, directory).strip().splitlines()[-1])
        out["python module psi1(x0)"] = reply["psi1"]
        out["python module Eigen cache sizes"] = repr(tuple(reply["blocking"]["used"]))
    return out


def first_difference(recorded, measured):
    """(name, recorded, measured) of the first recorded quantity that differs, or None."""
    for name, value in recorded.items():
        if name not in measured and name.startswith("python module"):
            continue  # the Python module's figures, when the module was not built or not asked for
        if measured.get(name) != value:
            return name, value, measured.get(name, "(missing)")
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("action", choices=("check", "write", "machine"))
    parser.add_argument("hindsight", nargs="?")
    parser.add_argument("workdir", nargs="?")
    parser.add_argument("--record", default=DEFAULT_RECORD)
    parser.add_argument("--python", help="the build's python/ folder: compare the Python module too")
    args = parser.parse_args()
    if args.action == "machine":
        print(json.dumps(machine(), indent=2))
        return 0
    if not args.hindsight or not args.workdir:
        parser.error("check and write need HINDSIGHT and WORKDIR")
    hindsight, work = os.path.abspath(args.hindsight), os.path.abspath(args.workdir)
    shutil.rmtree(work, ignore_errors=True)
    try:
        measured = measure(hindsight, work, python_dir=args.python)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.action == "write":
        previous = {}
        if os.path.isfile(args.record):
            with open(args.record) as f:
                previous = json.load(f)
        document = {k: v for k, v in previous.items() if k not in ("made_on", "solid_made_on", "quantities")}
        document["made_on"] = machine()
        document["quantities"] = measured
        with open(args.record + ".tmp", "w") as f:
            json.dump(document, f, indent=2)
            f.write("\n")
        os.replace(args.record + ".tmp", args.record)
        print(f"record: written to {args.record} ({len(measured)} quantities)")
        return 0
    with open(args.record) as f:
        record = json.load(f)
    here = machine()
    made = record["made_on"]
    print(f"record made on: {made.get('cpu')} (caches {made.get('caches')}); "
          f"this machine: {here.get('cpu')} (caches {here.get('caches')})")
    difference = first_difference(record["quantities"], measured)
    if difference:
        name, expected, got = difference
        print(f"record: DIFFERS, first at {name}: recorded {expected}, this machine {got}")
        return 1
    compared = sum(1 for name in record["quantities"] if name in measured)
    print(f"record: same bits ({compared} quantities)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
