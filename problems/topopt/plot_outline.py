#!/usr/bin/env python3
"""Picture of an exported design outline: reads DIR/design_final.dxf (written by `hindsight optimize`
or `hindsight export`; closed POLYLINEs in millimetres, outer boundaries counter-clockwise, holes
clockwise) and draws the filled outline with matplotlib (Debian python3-matplotlib).

    python3 problems/topopt/plot_outline.py DIR/design_final.dxf --out outline.png
"""
import argparse
import sys


def read_loops(path):
    """The loops of the DXF as lists of (x, y): pairs of lines (group code, value)."""
    with open(path) as f:
        lines = [line.strip() for line in f]
    pairs = list(zip(lines[0::2], lines[1::2]))
    loops, current, x, in_vertex = [], None, None, False
    for code, value in pairs:
        if code == "0":
            in_vertex = value == "VERTEX"  # the POLYLINE's own 10/20 is not a vertex
            x = None
            if value == "POLYLINE":
                current = []
            elif value == "SEQEND":
                if current:
                    loops.append(current)
                current = None
        elif in_vertex and current is not None and code == "10":
            x = float(value)
        elif in_vertex and current is not None and code == "20" and x is not None:
            current.append((x, float(value)))
            x = None
    return loops


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dxf")
    parser.add_argument("--out", required=True)
    parser.add_argument("--title", default="")
    args = parser.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.path import Path
    from matplotlib.patches import PathPatch

    loops = read_loops(args.dxf)
    if not loops:
        sys.exit(f"{args.dxf}: no outline loops")
    vertices, codes = [], []
    for loop in loops:
        vertices += loop + [loop[0]]
        codes += [Path.MOVETO] + [Path.LINETO] * (len(loop) - 1) + [Path.CLOSEPOLY]
    xs = [v[0] for v in vertices]
    ys = [v[1] for v in vertices]
    width = max(xs) - min(xs)
    height = max(ys) - min(ys)
    fig, ax = plt.subplots(figsize=(10, 10 * height / width + 0.6))
    ax.add_patch(PathPatch(Path(vertices, codes), facecolor="black", edgecolor="tab:red", linewidth=0.6))
    ax.set_xlim(min(xs) - 1, max(xs) + 1)
    ax.set_ylim(min(ys) - 1, max(ys) + 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    if args.title:
        ax.set_title(args.title)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)


if __name__ == "__main__":
    main()
