#!/usr/bin/python3
"""Tests of the PETSc trajectory type "hindsight" (petsc/, docs/guides/petsc.md), label petsc.

The programs (vanderpol.c, reaction_diffusion.c) are plain PETSc TSAdjoint programs; the trajectory is
chosen by options only. Each case runs PETSc's own memory trajectory and hindsight's strategies on the
same problem and the same number of ranks and requires the same bits (with every restored state checked
against a hash of the recorded one, -ts_trajectory_hindsight_verify), the byte budget respected, and
agreement with central differences; across 1, 2 and 4 ranks the gradients agree to the rounding that the
parallel transpose products of PETSc's matrices allow.

usage: run_petsc_tests.py CASE --lib LIB --vanderpol EXE --rd EXE [--mpirun MPIRUN]
"""
import argparse
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile

FAILURES = []


def fail(message):
    FAILURES.append(message)
    print("FAIL: " + message, flush=True)


def run(args, exe, options, ranks=1, expect_ok=True, direct=False):
    # direct: one rank without mpirun (a singleton MPI process), which starts several times faster.
    command = ([exe] if direct else [args.mpirun, "--oversubscribe", "--allow-run-as-root", "-n", str(ranks), exe]) + options
    env = dict(os.environ)
    env.setdefault("OMPI_MCA_ess_singleton_isolated", "1")  # a singleton without a helper daemon
    # Open MPI's session directory of its own: tests running side by side clean up each other's otherwise.
    env["OMPI_MCA_orte_tmpdir_base"] = args.work
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)
    output = done.stdout + done.stderr
    if expect_ok and done.returncode != 0:
        fail("%s exited %d:\n%s" % (" ".join(command), done.returncode, output[-3000:]))
        return None
    if not expect_ok and done.returncode == 0:
        fail("%s succeeded but should have failed:\n%s" % (" ".join(command), output[-2000:]))
    return output


def hindsight(args, spec, verify=True):
    options = ["-dll_append", args.lib, "-ts_trajectory_type", "hindsight", "-ts_trajectory_hindsight_storage", spec,
               "-ts_trajectory_view"]
    if verify:
        options.append("-ts_trajectory_hindsight_verify")
    return options


def view_counter(output, pattern):
    match = re.search(pattern, output)
    if not match:
        fail("no '%s' in the -ts_trajectory_view output:\n%s" % (pattern, output[-2000:]))
        return None
    return [int(g) for g in match.groups()]


def vdp_gradient(output):
    match = re.search(r"adjoint dJ/dx0 (\S+) (\S+) dJ/dmu (\S+)", output)
    return match.groups() if match else None


def check_budget(output, spec, states):
    """binomial/online/cams:checkpoints=C hold at most C + 1 states (storage/storage_docs.cpp); with
    stages=1 also the stage values of the step being recomputed and of the one restored."""
    size = view_counter(output, r"stored state: (\d+) doubles")
    stages = view_counter(output, r"stages per step: (\d+)")
    peak = view_counter(output, r"peak bytes in memory: (\d+)")
    if size is None or peak is None or stages is None:
        return
    allowed = states + (2 * stages[0] if "stages=1" in spec else 0)
    if peak[0] > allowed * size[0] * 8:
        fail("%s held %d bytes, more than %d states of %d doubles" % (spec, peak[0], allowed, size[0]))


# -------------------------------------------------------------------------------------------------------

VDP_SCHEMES = {
    "rk4": ["-ts_type", "rk", "-ts_rk_type", "4"],
    "cn": ["-ts_type", "cn", "-snes_rtol", "1e-12", "-snes_atol", "1e-14"],
    "theta": ["-ts_type", "theta", "-snes_rtol", "1e-12", "-snes_atol", "1e-14"],
    "rk5f-adaptive": ["-ts_type", "rk", "-ts_rk_type", "5f", "-ts_adapt_type", "basic", "-ts_rtol", "1e-6",
                      "-ts_atol", "1e-6"],
    "rk2a-adaptive": ["-ts_type", "rk", "-ts_rk_type", "2a", "-ts_adapt_type", "basic", "-ts_rtol", "1e-6",
                      "-ts_atol", "1e-6"],
    "cn-adaptive": ["-ts_type", "cn", "-ts_adapt_type", "basic", "-ts_rtol", "1e-4", "-ts_atol", "1e-4",
                    "-snes_rtol", "1e-12", "-snes_atol", "1e-14"],
}


def case_vanderpol(args, work):
    core = ["full", "online:checkpoints=5", "cams:checkpoints=5"]
    # Every strategy on one fixed-step and one adaptive scheme; the checkpointing ones on all.
    extra = ["full:stages=1", "online:checkpoints=5,stages=1", "packed", "disk:dir=%s" % work,
             "disk:dir=%s,stages=1" % work, "multilevel:ram=64,disk=160,dir=%s,costs=1e-6:2e-6:1e-5:1e-5" % work]
    for name, scheme in VDP_SCHEMES.items():
        adaptive = "adaptive" in name
        exact = core + (extra if name in ("rk4", "cn-adaptive") else [])
        reference_output = run(args, args.vanderpol, scheme + ["-ts_trajectory_type", "memory", "-fd"], direct=True)
        if reference_output is None:
            continue
        reference = vdp_gradient(reference_output)
        # The adjoint against central differences of forward solves: relative 1e-6 catches a wrong term
        # (a missing stage or step is O(h) = 1e-2 off) and is well above the differences' own error.
        ad = [float(x) for x in re.search(r"adjoint-decimal dJ/dx0 (\S+) (\S+) dJ/dmu (\S+)", reference_output).groups()]
        fd = [float(x) for x in re.search(r"fd-decimal dJ/dx0 (\S+) (\S+) dJ/dmu (\S+)", reference_output).groups()]
        # Adaptive steps move with the perturbation: the differences are good to about the tolerance.
        tolerance = 1e-6 if not adaptive else 10 * float(scheme[scheme.index("-ts_rtol") + 1])
        # PETSc 3.18's RK adjoint gets dJ/dmu wrong for tableaux with a zero weight b_i (5f, 5dp: its
        # b_i = 0 branch of the parameter update, TSAdjointStep_RK), with its own memory trajectory as
        # with ours; only dJ/dx0 is compared there.
        compared = 2 if "5f" in name else 3
        for a, f in list(zip(ad, fd))[:compared]:
            if abs(a - f) > tolerance * max(1.0, abs(f)):
                fail("vanderpol %s: adjoint %r vs central differences %r" % (name, a, f))
        specs = list(exact)
        if not adaptive:
            specs.append("binomial:checkpoints=10")
            if name == "rk4":
                specs.append("binomial:checkpoints=10,stages=1")
        for spec in specs:
            output = run(args, args.vanderpol, scheme + hindsight(args, spec), direct=True)
            if output is None:
                continue
            got = vdp_gradient(output)
            if got != reference:
                fail("vanderpol %s %s: %s, PETSc memory %s" % (name, spec, got, reference))
            if spec.startswith(("binomial:checkpoints=10", "online:checkpoints=5", "cams:checkpoints=5")):
                check_budget(output, spec, 11 if spec.startswith("binomial") else 6)
                recomputed = view_counter(output, r"recomputed steps: (\d+) \(checkpoint schedule\)")
                if recomputed and recomputed[0] == 0:
                    fail("vanderpol %s %s recomputed nothing; the checkpoints were not exercised" % (name, spec))
            if "stages=1" in spec and spec.startswith(("full", "disk")):
                served = view_counter(output, r"adjoint steps from stored stages: (\d+)")
                steps = view_counter(output, r"steps: (\d+),")
                if served and steps and served[0] != steps[0]:
                    fail("vanderpol %s %s: %d of %d adjoint steps from stored stages" % (name, spec, served[0], steps[0]))
        if name not in ("rk4", "cn-adaptive"):
            continue
        # Lossy storage: not the same bits, but the gradient within the tolerance's reach.
        output = run(args, args.vanderpol, scheme + hindsight(args, "lossy:codec=round,tolerance=1e-10", verify=False),
                     direct=True)
        if output is not None:
            got = [float.fromhex(x) for x in vdp_gradient(output)]
            ref = [float.fromhex(x) for x in reference]
            for g, r in zip(got, ref):
                if abs(g - r) > 1e-7 * max(1.0, abs(r)):
                    fail("vanderpol %s lossy: %r vs %r" % (name, g, r))
    # An FSAL tableau (Dormand-Prince): the recomputed first stage is evaluated afresh, a few ulps off
    # the forward sweep's copied one (docs/guides/petsc.md); stored stages give the bits back.
    scheme = ["-ts_type", "rk", "-ts_rk_type", "5dp", "-ts_adapt_type", "basic", "-ts_rtol", "1e-6", "-ts_atol", "1e-6"]
    reference = vdp_gradient(run(args, args.vanderpol, scheme + ["-ts_trajectory_type", "memory"], direct=True) or "")
    output = run(args, args.vanderpol, scheme + hindsight(args, "full:stages=1"), direct=True)
    if output is not None and vdp_gradient(output) != reference:
        fail("vanderpol 5dp full:stages=1: %s vs %s" % (vdp_gradient(output), reference))
    output = run(args, args.vanderpol, scheme + hindsight(args, "online:checkpoints=5", verify=False), direct=True)
    if output is not None:
        got = [float.fromhex(x) for x in vdp_gradient(output)]
        for g, r in zip(got, [float.fromhex(x) for x in reference]):
            if abs(g - r) > 1e-13 * max(1.0, abs(r)):
                fail("vanderpol 5dp online: %r vs %r" % (g, r))


# -------------------------------------------------------------------------------------------------------

def read_petsc_vec(path):
    with open(path, "rb") as f:
        data = f.read()
    classid, n = struct.unpack(">ii", data[:8])
    if classid != 1211214:
        raise ValueError("%s is not a PETSc Vec" % path)
    return list(struct.unpack(">%dd" % n, data[8:8 + 8 * n]))


RD_SCHEMES = {
    "rk4": ["-ts_rk_type", "4"],
    # Newton + GMRES on 4 oversubscribed ranks are slow; a small grid and few steps keep the case short.
    "cn": ["-ts_type", "cn", "-grid", "16", "-ts_max_steps", "10", "-snes_rtol", "1e-13", "-snes_atol", "1e-15", "-ksp_rtol", "1e-14",
           "-ksp_atol", "1e-16"],
    # A first step of 4 that the adaptor rejects (it takes 0.96), replayed in every recomputation of it.
    "rk5f-adaptive": ["-ts_rk_type", "5f", "-ts_adapt_type", "basic", "-ts_rtol", "1e-10", "-ts_atol", "1e-10",
                      "-ts_max_time", "10", "-ts_dt", "4", "-ts_max_steps", "100000"],
}


def case_ranks(args, work, name):
    per_ranks = {}
    scheme = RD_SCHEMES[name]
    adaptive = "adaptive" in name
    for ranks in (1, 2, 4):
        # The checkpointing strategies on every rank count; stored stages and per-rank disk files on 2.
        specs = ["online:checkpoints=4"] if adaptive else ["binomial:checkpoints=5"]
        if ranks == 2:
            specs += ["cams:checkpoints=4", "full:stages=1", "disk:dir=%s/rank%%r" % work]
        reference_file = os.path.join(work, "rd-%s-%d-memory.bin" % (name, ranks))
        if run(args, args.rd, scheme + ["-ts_trajectory_type", "memory", "-out", reference_file], ranks) is None:
            continue
        reference = open(reference_file, "rb").read()
        per_ranks[(name, ranks)] = read_petsc_vec(reference_file)
        for spec in specs:
            out = os.path.join(work, "rd-%s-%d-hs.bin" % (name, ranks))
            output = run(args, args.rd, scheme + hindsight(args, spec) + ["-out", out], ranks)
            if output is None:
                continue
            if open(out, "rb").read() != reference:
                fail("reaction-diffusion %s on %d ranks, %s: lambda(0) differs from PETSc memory's" % (name, ranks, spec))
            if spec.startswith(("binomial", "online", "cams")):
                check_budget(output, spec, 6 if spec.startswith("binomial") else 5)
    # Across rank counts: MPIAIJ's transpose product sums the off-process part in another order,
    # so the bits may move; the vectors agree to a few ulps of their largest entry per step.
    base = per_ranks.get((name, 1))
    for ranks in (2, 4):
        other = per_ranks.get((name, ranks))
        if base is None or other is None:
            continue
        scale = max(abs(x) for x in base)
        worst = max(abs(a - b) for a, b in zip(base, other))
        limit = (1e-9 if name == "cn" else 1e-13) * scale
        if worst > limit:
            fail("reaction-diffusion %s: 1 vs %d ranks differ by %.3g (limit %.3g)" % (name, ranks, worst, limit))
        else:
            print("reaction-diffusion %s: 1 vs %d ranks differ by %.3g of %.3g" % (name, ranks, worst, scale))


def case_fd(args, work):
    # 2 ranks, binomial checkpoints: the adjoint against central differences of forward solves.
    output = run(args, args.rd, ["-ts_rk_type", "4", "-fd"] + hindsight(args, "binomial:checkpoints=5"), 2)
    if output is None:
        return
    checks = re.findall(r"check point (\d) adjoint (\S+) fd (\S+)", output)
    if len(checks) != 3:
        fail("reaction-diffusion -fd printed %d checks" % len(checks))
    for point, adjoint, fd in checks:
        a, f = float(adjoint), float(fd)
        if abs(a - f) > 1e-7 * max(abs(f), 1e-2):
            fail("reaction-diffusion point %s: adjoint %r vs central differences %r" % (point, a, f))


def case_failures(args, work):
    # Bad input: the option named, the strategies listed, nothing run.
    output = run(args, args.vanderpol, hindsight(args, "binomial:checkpoints=0"), expect_ok=False)
    if output and "-ts_trajectory_hindsight_storage" not in output:
        fail("a bad spec's message does not name the option:\n" + output[-1500:])
    output = run(args, args.vanderpol, hindsight(args, "nosuch"), expect_ok=False)
    if output and "binomial" not in output:
        fail("an unknown strategy's message does not list the known ones:\n" + output[-1500:])
    output = run(args, args.vanderpol, hindsight(args, "hermite"), expect_ok=False)
    if output and "time derivative" not in output:
        fail("hermite is not refused with its reason:\n" + output[-1500:])
    # binomial needs the number of steps in advance; adaptive steps do not give it.
    output = run(args, args.vanderpol, VDP_SCHEMES["rk5f-adaptive"] + hindsight(args, "binomial:checkpoints=5"),
                 expect_ok=False)
    if output and "number of steps" not in output:
        fail("binomial with adaptive steps is not refused with its reason:\n" + output[-1500:])
    # multilevel under MPI needs its costs given (measured costs differ between ranks).
    output = run(args, args.rd, hindsight(args, "multilevel:ram=1MiB,disk=1MiB"), 2, expect_ok=False)
    if output and "costs=" not in output:
        fail("multilevel without costs under MPI is not refused:\n" + output[-1500:])
    # A budget too small for the checkpoints: every rank stops with the budget message.
    output = run(args, args.rd, hindsight(args, "full:budget=64KiB"), 2, expect_ok=False)
    if output and ("budget" not in output or "failed on rank" not in output):
        fail("an exhausted budget does not stop the run with its message:\n" + output[-1500:])
    # An I/O error on one rank only (its directory is a file): every rank stops and names rank 1.
    bad = os.path.join(work, "faulty")
    os.makedirs(bad, exist_ok=True)
    open(os.path.join(bad, "rank1"), "w").close()
    output = run(args, args.rd, hindsight(args, "disk:dir=%s/rank%%r" % bad), 2, expect_ok=False)
    # The first rank to raise the error aborts the job (PETSc's error in main), which may cut the other
    # rank's print short; both raise the same message (on rank 0 it can only come from the agreement).
    if output is not None:
        if not re.search(r"\[[01]\]PETSC ERROR: hindsight trajectory .* failed on rank 1 of 2: .*rank1", output):
            fail("the run did not stop with rank 1's I/O error:\n%s" % output[-3000:])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("case", choices=["vanderpol", "fd", "failures"] + ["ranks-" + n for n in RD_SCHEMES])
    parser.add_argument("--lib", required=True)
    parser.add_argument("--vanderpol", required=True)
    parser.add_argument("--rd", required=True)
    parser.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix="hindsight-petsc-")
    args.work = work
    try:
        if args.case.startswith("ranks-"):
            case_ranks(args, work, args.case[len("ranks-"):])
        else:
            {"vanderpol": case_vanderpol, "fd": case_fd, "failures": case_failures}[args.case](args, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if FAILURES:
        print("%d failure(s)" % len(FAILURES))
        return 1
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
