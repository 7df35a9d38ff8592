#!/usr/bin/python3
"""End to end: `hindsight evaluate --gradient` with a multilevel storage whose disk level is damaged while
the run uses it must exit 3 naming the .slots file and the slot, never write a gradient.

usage: corrupt_multilevel_slot.py HINDSIGHT WORK_DIR

The run (the 20 x 4 rod over 60 s, 3 states in RAM, 16 KiB of disk slots) writes its disk slots in the
forward sweep and reads them back in the backward sweep. Meanwhile this script stops the process
(SIGSTOP), XORs one byte into every slot record that is intact at that moment, and lets it go on
(SIGCONT), every 0.02 s until it ends. A record is intact when its trailer (storage/multilevel_storage.cpp:
the slot index and FNV-1a 64 over the index and the state) matches; only intact records are damaged, so
a slot rewritten by the run is damaged again and none is ever repaired by a second XOR. Whatever slot the
backward sweep reads first is then damaged, and the read must refuse it.
"""
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import time


TRAILER = 16
FNV_OFFSET = 0xCBF29CE484222325
FNV_PRIME = 0x100000001B3


def fnv1a(data, h=FNV_OFFSET):
    for byte in data:
        h = ((h ^ byte) * FNV_PRIME) & 0xFFFFFFFFFFFFFFFF
    return h


def record_bytes(path):
    """The size of one slot record: the smallest state size for which some record's trailer validates
    (slots are written at slot * record, so the file may have holes)."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    for state in range(8, 4097, 8):
        size = state + TRAILER
        for start in range(0, len(data) - size + 1, size):
            slot, check = struct.unpack_from("<QQ", data, start + state)
            if slot == start // size and check == fnv1a(data[start:start + state], fnv1a(struct.pack("<Q", slot))):
                return size
    return None


def damage_intact_slots(path, size):
    damaged = 0
    with open(path, "r+b") as f:
        data = bytearray(f.read())
        for start in range(0, len(data) - size + 1, size):
            state = bytes(data[start:start + size - TRAILER])
            slot, check = struct.unpack_from("<QQ", data, start + size - TRAILER)
            if slot == start // size and check == fnv1a(state, fnv1a(struct.pack("<Q", slot))):
                f.seek(start + 3)
                f.write(bytes([data[start + 3] ^ 0x5A]))
                damaged += 1
    return damaged


def main():
    cli, work = sys.argv[1], sys.argv[2]
    shutil.rmtree(work, ignore_errors=True)
    slots_dir = os.path.join(work, "slots")
    os.makedirs(slots_dir)
    gradient = os.path.join(work, "gradient.h5")
    command = [cli, "evaluate", "--set", "rod.elementsAlongLength=20", "--set", "rod.elementsThroughHeight=4",
               "--set", "rod.modeCount=4", "--set", "rod.endTime=60",
               "--set", f"simulation.storage=multilevel:ram=480,disk=16KiB,costs=1:1:0:0,dir={slots_dir}",
               "--gradient", gradient]
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    size = None
    damaged = 0
    deadline = time.monotonic() + 600
    while run.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
        files = [name for name in os.listdir(slots_dir) if name.endswith(".slots")]
        if not files:
            continue
        path = os.path.join(slots_dir, files[0])
        try:
            run.send_signal(signal.SIGSTOP)
        except ProcessLookupError:
            break
        try:
            if size is None and os.path.getsize(path) >= 2 * TRAILER:
                size = record_bytes(path)
            if size is not None:
                damaged += damage_intact_slots(path, size)
        except FileNotFoundError:
            pass  # the run ended and removed its file
        finally:
            try:
                run.send_signal(signal.SIGCONT)
            except ProcessLookupError:
                pass
    if run.poll() is None:
        run.kill()
        print("the run did not end within 600 s")
        return 1
    out, err = run.communicate()
    print(f"exit {run.returncode}, {damaged} slot records damaged, record {size} bytes\nstderr: {err.strip()}")
    if damaged == 0:
        print("no slot was damaged: the run ended before its disk level could be reached")
        return 1
    ok = (run.returncode == 3 and re.search(re.escape(slots_dir) + r"/hindsight-multilevel-\S*\.slots", err)
          and re.search(r"slot \d+", err)
          and "corrupted" in err and not os.path.exists(gradient))
    if not ok:
        print("expected exit 3 naming the .slots file and the slot, and no gradient file")
        return 1
    print("corrupted multilevel slot: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
