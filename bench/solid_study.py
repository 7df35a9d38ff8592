#!/usr/bin/python3
"""The connecting rod optimised as a solid, against the plate (docs/tutorials/rod_as_solid.md).

Usage:
  /usr/bin/python3 bench/solid_study.py sections RUN [--png FILE] [--stations N] [--hindsight PATH]
  /usr/bin/python3 bench/solid_study.py study [--mesh NX NY NZ] [--iterations K] [--threads T]
                                              [--dir DIR] [--hindsight PATH] [--png FILE]

sections: the density in the (y, z) cross-section at N stations along the rod of a finished solid run
  (hindsight optimize with rod.elementsThroughThickness >= 1): the run's final design is exported by
  `hindsight export RUN` (the densities of the whole body as a .vtu, mirrored with mid-plane symmetry),
  drawn as one panel per station (black = 1, white = 0; y up, z across, to scale) under the side view of
  the thickness-mean density with the stations marked, and described on stdout: per station the rows
  (through the height) that hold material and how much of the thickness each fills, and whether the
  section has full-thickness flanges at the top and bottom and where its web lies: at the mid-plane (an
  I-section), at the faces (a box section), across the thickness, or none (two bare flanges).

study: the whole comparison, each step timed with /usr/bin/time (CPU seconds, peak RSS) and the machine's
  load (uptime) before and after: one evaluation with the gradient of x0 on the solid mesh (mid-plane
  symmetry), the solid optimisation (--iterations K), the plate optimisation with the same iteration
  cap and defaults (the README's command with --iterations K), export of the solid's STL, densities and
  motion (hindsight export --motion), and the cross-sections. Writes DIR/study.json and prints a
  Markdown table. Long: at 100 x 12 x 8 about 15 s a gradient on an idle machine of 2 cores.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_CLI = os.path.join(HERE, "..", "build", "hindsight")


def read_vtu_densities(path):
    """(points per axis, cell densities) of a writeDensityVtu file: densities as (nx, ny, layers)."""
    with open(path) as f:
        text = f.read()
    cells = int(re.search(r'NumberOfCells="(\d+)"', text).group(1))
    block = re.search(r'Name="density" format="ascii">\n(.*?)</DataArray>', text, re.S).group(1)
    values = np.array(block.split(), dtype=float)
    assert values.size == cells, (values.size, cells)
    return values


def run_config(run):
    import h5py

    with h5py.File(os.path.join(run, "results.h5"), "r") as f:
        for key in ("configuration", "config"):
            if key in f.attrs:
                return json.loads(f.attrs[key])
        raise SystemExit("no configuration attribute in " + run + "/results.h5")


def solid_densities(run, cli):
    """The final design's densities of the whole body as (nx, ny, layers) and the rod section."""
    config = run_config(run)
    rod = config["rod"]
    nx, ny, nz = rod["elementsAlongLength"], rod["elementsThroughHeight"], rod["elementsThroughThickness"]
    if nz < 1:
        raise SystemExit(run + " is a plate run (rod.elementsThroughThickness = 0)")
    layers = 2 * nz if rod["midPlaneSymmetry"] else nz
    with tempfile.TemporaryDirectory() as tmp:
        stem = os.path.join(tmp, "design")
        subprocess.run([cli, "export", run, "--out", stem], check=True, stdout=subprocess.DEVNULL)
        values = read_vtu_densities(stem + ".vtu")
    return values.reshape(nx, ny, layers), rod


def classify(section, iso=0.5):
    """The filled fraction of the thickness per row (y, bottom first) and the section's kind.

    Flanges: the top and the bottom row filled across the whole thickness. The web is the material in
    the rows between them: at the mid-plane only (the middle half of the layers) an I-section, at the
    faces only a box section (two side walls), both a mixed web, none two bare flanges."""
    solid = section >= iso
    fill = solid.mean(axis=1)
    rows = np.nonzero(fill > 0)[0]
    if rows.size == 0:
        return fill, "empty"
    ny, layers = section.shape
    bottom, top = rows.min(), rows.max()
    flanges = fill[bottom] >= 0.999 and fill[top] >= 0.999 and bottom < ny // 3 and top >= ny - ny // 3
    if not flanges:
        return fill, "no flanges"
    web = solid[bottom + 1:top].any(axis=0) if top > bottom + 1 else np.zeros(layers, bool)
    web_rows = int(solid[bottom + 1:top].any(axis=1).sum()) if top > bottom + 1 else 0
    middle = np.zeros(layers, bool)
    middle[layers // 4:layers - layers // 4] = True
    if not web.any():
        return fill, "two flanges, no web"
    if np.all(fill[bottom:top + 1] >= 0.999):
        return fill, "solid (full thickness from flange to flange)"
    where = "%d of %d rows" % (web_rows, top - bottom - 1)
    if not web[~middle].any():
        return fill, "I-section (web at the mid-plane in " + where + ")"
    if not web[middle].any():
        return fill, "box section (webs at the faces in " + where + ")"
    return fill, "flanges with a web across the thickness in " + where


def sections(run, png, stations, cli):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rho, rod = solid_densities(run, cli)
    nx, ny, layers = rho.shape
    length, height, thickness = 1e3 * rod["length"], 1e3 * rod["height"], 1e3 * rod["thickness"]
    columns = sorted(set(int(round(f * (nx - 1))) for f in np.linspace(0.08, 0.92, stations)))
    report = []
    for i in columns:
        fill, kind = classify(rho[i])
        x = (i + 0.5) * length / nx
        report.append(dict(column=i, x_mm=x, kind=kind, fill=[round(float(v), 3) for v in fill]))
        print("x = %6.1f mm (column %3d): %s" % (x, i, kind))
        print("    filled thickness per row, bottom to top: " + " ".join("%.2f" % v for v in fill))
    counts = {}
    for r in report:
        counts[r["kind"]] = counts.get(r["kind"], 0) + 1
    print("stations: " + ", ".join("%d %s" % (n, k) for k, n in counts.items()))

    fig = plt.figure(figsize=(1.1 * len(columns) + 1.0, 4.2), dpi=80)
    grid = fig.add_gridspec(2, len(columns), height_ratios=[1.0, 2.4])
    side = fig.add_subplot(grid[0, :])
    side.imshow(rho.mean(axis=2).T, origin="lower", cmap="gray_r", vmin=0, vmax=1,
                extent=[0, length, -height / 2, height / 2], aspect="auto", interpolation="nearest")
    for i in columns:
        side.axvline((i + 0.5) * length / nx, color="tab:red", lw=0.8)
    side.set_title("thickness-mean density and stations (x in mm)", fontsize=8)
    side.tick_params(labelsize=7)
    for n, i in enumerate(columns):
        ax = fig.add_subplot(grid[1, n])
        ax.imshow(rho[i], origin="lower", cmap="gray_r", vmin=0, vmax=1,
                  extent=[-thickness / 2, thickness / 2, -height / 2, height / 2], interpolation="nearest")
        ax.set_title("x=%.0f" % ((i + 0.5) * length / nx), fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([] if n else [-height / 2, 0, height / 2])
        ax.tick_params(labelsize=6)
    fig.suptitle("cross-sections (y up, z across, mm) of " + os.path.basename(os.path.normpath(run)), fontsize=8)
    fig.savefig(png, bbox_inches="tight")
    print("wrote " + png)
    return report


def timed(command, log):
    """Runs command under /usr/bin/time -v; returns (wall s, CPU s, peak RSS MB, stdout)."""
    started = time.time()
    result = subprocess.run(["/usr/bin/time", "-v"] + command, capture_output=True, text=True)
    wall = time.time() - started
    with open(log, "w") as f:
        f.write(" ".join(command) + "\n" + result.stdout + result.stderr)
    if result.returncode != 0:
        raise SystemExit("failed (" + log + "): " + " ".join(command))
    user = float(re.search(r"User time \(seconds\): ([\d.]+)", result.stderr).group(1))
    system = float(re.search(r"System time \(seconds\): ([\d.]+)", result.stderr).group(1))
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", result.stderr).group(1)) / 1024.0
    return dict(wall_s=round(wall, 1), cpu_s=round(user + system, 1), peak_rss_mb=round(rss, 1)), result.stdout


def uptime():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def final_line(stdout):
    match = re.search(r"psi1: ([\d.e+-]+) -> ([\d.e+-]+).*V/V0 ([\d.]+); (\d+) evaluations", stdout)
    return dict(psi1_x0=float(match.group(1)), psi1=float(match.group(2)), volume_fraction=float(match.group(3)),
                evaluations=int(match.group(4)))


def study(args):
    os.makedirs(args.dir, exist_ok=True)
    nx, ny, nz = args.mesh
    mesh = ["--set", "rod.elementsAlongLength=%d" % nx, "--set", "rod.elementsThroughHeight=%d" % ny,
            "--set", "rod.elementsThroughThickness=%d" % nz, "--set", "rod.midPlaneSymmetry=true"]
    # --set SETTING for every run (e.g. optimization.moveLimit=0.5, the default before it became 0.2).
    threads = ["--threads", str(args.threads)] + [word for setting in args.set for word in ("--set", setting)]
    out = dict(mesh=[nx, ny, nz], symmetry=True, iterations=args.iterations, threads=args.threads,
               settings=args.set, load_before=uptime())
    cli = args.hindsight
    t, stdout = timed([cli, "evaluate", "--json", "--gradient", os.path.join(args.dir, "gradient_x0.h5"), "--force"]
                      + mesh + threads, os.path.join(args.dir, "evaluate.log"))
    report = json.loads(stdout[stdout.index("{"):])
    out["gradient_x0"] = dict(t, design_variables=int(np.prod([nx - 2, ny, nz])), psi1=report.get("psi1"))
    solid = os.path.join(args.dir, "solid")
    t, stdout = timed([cli, "optimize", "--iterations", str(args.iterations), "--out", solid, "--force"] + mesh
                      + threads, os.path.join(args.dir, "solid.log"))
    out["solid"] = dict(t, **final_line(stdout))
    plate = os.path.join(args.dir, "plate")
    t, stdout = timed([cli, "optimize", "--iterations", str(args.iterations), "--out", plate, "--force"] + threads,
                      os.path.join(args.dir, "plate.log"))
    out["plate"] = dict(t, **final_line(stdout))
    # The plate on the solid's in-plane mesh: the same resolution along the length and the height.
    t, stdout = timed([cli, "optimize", "--iterations", str(args.iterations), "--out", plate + "_same_mesh",
                       "--force"] + mesh[:4] + threads, os.path.join(args.dir, "plate_same_mesh.log"))
    out["plate_same_mesh"] = dict(t, **final_line(stdout))
    t, stdout = timed([cli, "export", solid, "--motion", "--force"], os.path.join(args.dir, "motion.log"))
    out["motion"] = dict(t, output=stdout.strip())
    out["load_after"] = uptime()
    out["sections"] = sections(solid, args.png or os.path.join(args.dir, "sections.png"), args.stations, cli)
    with open(os.path.join(args.dir, "study.json"), "w") as f:
        json.dump(out, f, indent=1)
    runs = [out["solid"], out["plate_same_mesh"], out["plate"]]
    print("| | solid %d x %d x %d (half) | plate %d x %d | plate 200 x 12 (default) |" % (nx, ny, nz, nx, ny))
    print("|---|---|---|---|")
    print("| psi1(x0) -> final | " + " | ".join("%.4f -> %.4f" % (r["psi1_x0"], r["psi1"]) for r in runs) + " |")
    print("| V/V0 | " + " | ".join("%.3f" % r["volume_fraction"] for r in runs) + " |")
    print("| evaluations | " + " | ".join("%d" % r["evaluations"] for r in runs) + " |")
    print("| wall, CPU [s] | " + " | ".join("%.0f, %.0f" % (r["wall_s"], r["cpu_s"]) for r in runs) + " |")
    print("| peak RSS [MB] | " + " | ".join("%.0f" % r["peak_rss_mb"] for r in runs) + " |")
    g = out["gradient_x0"]
    print("one gradient at x0 (%d design variables): wall %.1f s, CPU %.1f s, peak RSS %.0f MB"
          % (g["design_variables"], g["wall_s"], g["cpu_s"], g["peak_rss_mb"]))
    print("load: " + out["load_before"] + " / " + out["load_after"])


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    a = sub.add_parser("sections")
    a.add_argument("run")
    a.add_argument("--png", default=None)
    a.add_argument("--stations", type=int, default=9)
    a.add_argument("--hindsight", default=DEFAULT_CLI)
    b = sub.add_parser("study")
    b.add_argument("--mesh", type=int, nargs=3, default=[100, 12, 8])
    b.add_argument("--iterations", type=int, default=50)
    b.add_argument("--threads", type=int, default=2)
    b.add_argument("--dir", default="solid_study")
    b.add_argument("--stations", type=int, default=9)
    b.add_argument("--png", default=None)
    b.add_argument("--hindsight", default=DEFAULT_CLI)
    b.add_argument("--set", action="append", default=[], metavar="SETTING",
                   help="a configuration setting for every run, as hindsight's --set")
    args = parser.parse_args()
    if args.command == "sections":
        if args.stations < 1:
            parser.error("--stations must be >= 1")
        sections(args.run, args.png or os.path.join(args.run, "sections.png"), args.stations, args.hindsight)
    else:
        study(args)


if __name__ == "__main__":
    sys.exit(main())
