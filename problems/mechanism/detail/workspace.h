// A MechanismProblem's workspace: the buffers of every pass (double and dual numbers of each width, full
// coordinates and chord system), the warm start of the position solve, and the results kept for the
// point last evaluated, which make the engine's several calls at one point cheap without making a result
// depend on the call history (docs/design.md §10; mechanism_problem.h, "Determinism and cost").
// Internal to problems/mechanism/ (not installed).
#pragma once

#include <hindsight/problems/mechanism/detail/member_invariants.h>
#include <hindsight/problems/mechanism/detail/system.h>

#include <cassert>
#include <vector>

namespace hindsight::mechanism::detail {

struct Work final : ProblemWorkspace {
  Work(const System& I, const System& C)
      : d(I.nz, I.m, I.f, I.n),
        s(I.nz, I.m, I.f, I.n),
        l(I.nz, I.m, I.f, I.n),
        cd(C.nz, C.m, C.f, 1),
        cs(C.nz, C.m, C.f, 1),
        c2(C.nz, C.m, C.f, 1),
        c3(C.nz, C.m, C.f, 1),
        c9(C.nz, C.m, C.f, 1),
        zStar(I.nz),
        zChord(C.nz),
        sigmaLast(C.f),
        zLast(C.nz),
        blockLu(C.blocks.luSize),
        blockPiv(C.blocks.pivSize),
        blockIn(C.m),
        blockOut(C.m),
        blockScratch(C.blocks.maxSize),
        stepLu(C.blocks.maxSize * C.blocks.maxSize),
        stepPiv(C.blocks.maxSize),
        stepX(C.blocks.maxSize),
        sigmaKinematics(C.f),
        sigmaDotKinematics(C.f),
        sigmaTwo(C.f),
        sigmaDotTwo(C.f),
        sigma(C.f),
        sigmaDot(C.f),
        sigmaDdot(C.f),
        luStar(I.m * I.m),
        pivStar(I.m),
        x0(I.m),
        x1(I.m),
        dualIn(C.m * 2 * (MechanismProblem::kMaxFree + 1)),
        dualSolve(C.m * 2 * (MechanismProblem::kMaxFree + 1)),
        dualScratch(C.blocks.maxSize * 2 * (MechanismProblem::kMaxFree + 1)),
        mu(I.f),
        nu(I.nz),
        fScratch(I.f),
        meeSym(I.n, I.n),
        meeQ(I.n),
        h(I.n),
        a1(I.n),
        keeQ(I.n),
        ctV(I.n),
        meeA(I.n),
        ctA(I.n),
        meeV(I.n),
        along(I.n),
        vel(I.n),
        uq(I.n),
        muCt(I.n),
        muCtT(I.n),
        muKee(I.n),
        muMee(I.n),
        qKey(I.n),
        vKey(I.n),
        aKey(I.n) {
    // The chord system's dual buffers, whose rows a masked pass leaves alone (System::constraints()).
    cs.clear(2 * C.f);
    c2.clear(2);
    c3.clear(3);
    c9.clear(9);
    timeCache.positions.assign(C.m, 0.0);
    timeCache.jac.assign(C.inactiveJacIndex.size(), 0.0);
    timeCache.phit.assign(C.m, 0.0);
    timeCache.quad.assign(C.m, 0.0);
  }
  Buffers<double> d;
  Buffers<ADS> s;
  Buffers<ADL> l;
  // The chord system (problems/mechanism/mechanism_problem.h): rigid coordinates and c = b q.
  Buffers<double> cd;
  Buffers<ADS> cs;
  Buffers<AD2> c2;
  Buffers<AD3> c3;  ///< the parameter product
  Buffers<AD9> c9;  ///< the Jacobians without free coordinates
  Vector zStar;     ///< full coordinates of the reference path
  Vector zChord;    ///< solved positions of the chord system
  // Warm start of Newton: the last solved (t, sigma, z).
  bool warm = false;
  double tLast = 0.0;
  Vector sigmaLast, zLast;
  // The chord system's Phi_u at the solved positions, factorised block by block (the kinematics' solves
  // and the dual passes'), and scratch of the block solves (by equation, by unknown, one block).
  std::vector<double> blockLu;
  std::vector<int> blockPiv;
  std::vector<double> blockIn, blockOut, blockScratch;
  // Scratch of one block's Newton step in the position solve.
  std::vector<double> stepLu;
  std::vector<int> stepPiv;
  std::vector<double> stepX;
  // The chord kinematics in cd were computed at (tKinematics, sigmaKinematics, sigmaDotKinematics):
  // the engine asks for the mass matrix, the Jacobians and the force (or the parameter product) at one
  // point.
  bool kinematicsValid = false, velocitiesValid = false;
  double tKinematics = 0.0;
  Vector sigmaKinematics, sigmaDotKinematics;
  // The same for the two-direction dual kinematics in c2 (twoDirectionKinematics()).
  bool twoValid = false;
  int twoSeed = 0;
  double tTwo = 0.0;
  Vector sigmaTwo, sigmaDotTwo;
  // sigma = (free coordinates, b q) and its derivatives at the current call.
  Vector sigma, sigmaDot, sigmaDdot;
  // Phi_u at the solved positions, factorised (the implicit-function step of the dual passes).
  std::vector<double> luStar;
  std::vector<int> pivStar;
  std::vector<double> x0, x1;  ///< scratch of the dual solves (kinematics())
  // The chord system's dual solves in all directions at once (System::blockSolveActive()).
  std::vector<double> dualIn, dualSolve, dualScratch;
  System::TimeCache timeCache;  ///< the chord system's parts that depend on time alone
  Vector mu, nu, fScratch;
  // The symmetric part of M_ee: once per solve for a workspace made for a fixed p.
  bool parametersFixed = false;
  Matrix meeSym;
  Matrix meeRotationSym;  ///< M_ee^xy's of a spatial member (View::meeRotation), empty for a plate
  // Products of the modal coordinates with the invariant matrices (modalProducts()), the member's
  // moments, and the q, q', a they were formed from (kept only for a fixed p).
  Vector meeQ, h, a1, keeQ, ctV, meeA, ctA, meeV, along, vel, uq;
  // Products of mu's modal part with the invariant matrices (chordStateVjp()).
  Vector muCt, muCtT, muKee, muMee;
  double moments[kMoments] = {};
  Vector qKey, vKey, aKey;
  bool qKept = false, vKept = false, aKept = false, aZero = false, vJacobian = false, aJacobian = false;
};

inline Work& workOf(ProblemWorkspace* ws) {
  assert(ws != nullptr);
  return static_cast<Work&>(*ws);
}

}  // namespace hindsight::mechanism::detail
