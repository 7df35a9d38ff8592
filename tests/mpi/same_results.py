"""Exit 0 when two results.h5 files hold the same bits in every dataset and attribute except the
wall-clock columns, the number of ranks that wrote them (and the hashes over them); otherwise print
what differs and exit 1."""
import sys

import h5py


def differences(a_path, b_path):
    a, b = h5py.File(a_path, "r"), h5py.File(b_path, "r")
    found = []

    def visit(name, obj):
        if not isinstance(obj, h5py.Dataset) or name.endswith("_seconds"):
            return
        if name not in b:
            found.append(name + " (missing)")
        elif obj[()].tobytes() != b[name][()].tobytes() or obj.shape != b[name].shape:
            found.append(name)

    a.visititems(visit)
    for key in a.attrs:
        if key not in ("content_hash", "ranks") and (key not in b.attrs or str(a.attrs[key]) != str(b.attrs[key])):
            found.append("@" + key)
    return found


if __name__ == "__main__":
    diff = differences(sys.argv[1], sys.argv[2])
    if diff:
        print(sys.argv[1], "and", sys.argv[2], "differ in:", ", ".join(diff))
        sys.exit(1)
    print(sys.argv[1], "and", sys.argv[2], "hold the same bits")
