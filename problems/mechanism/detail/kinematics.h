// The kinematics of the planar mechanism (docs/design.md §10): the positions solved from the constraints
// block by block, and z, z', zeta and R = [I; -Phi_u^-1 Phi_y] at (t, y, y') in double or in dual numbers
// (the implicit function's derivatives). Defined in kinematics.cpp and instantiated there for the scalar
// types the passes use. Internal to problems/mechanism/ (not installed).
#pragma once

#include <hindsight/problems/mechanism/detail/workspace.h>

namespace hindsight::mechanism::detail {

/// The dependent coordinates of the chord system at (t, sigma) into w.zChord (see mechanism_problem.h on
/// determinism). They depend on the modal coordinates only through c = b q, the last entry of sigma.
void solvePositions(const System& C, double t, const Vector& sigma, Work& w);

/// Which part of kinematics(): the position level (z, Phi_u factorised, R), the velocity level (z',
/// zeta; needs the position level of the same point in B), or both.
enum class Part { All, Positions, Velocities };

/// z, z', zeta, R at (t, y, y') in scalar type T with nd derivative directions: y, y' and b are given in
/// B.y, B.v, B.b; zStar holds the solved positions (and for dual passes w.luStar, or for the chord
/// system w.blockLu, the factorised Phi_u).
/// known (dual passes whose b is constant): the double kinematics of the same point (all parts, at the
/// same y'). Its R's dependent rows are the implicit function's derivatives, du = R_u dy, and its R, z'
/// and zeta are the solves' values; without it one Newton correction in dual numbers gives du (b may
/// then carry derivatives) and the solves refine their own double solution.
template <typename T>
void kinematics(const System& I, double t, Buffers<T>& B, Work& w, const Vector& zStar, int nd,
                Part part = Part::All, const Buffers<double>* known = nullptr);

/// sigma = (free coordinates, b q) and its first two derivatives (a may be null: sigma'' not needed).
void chordInputs(const System& I, const View& P, ConstVectorRef y, ConstVectorRef v, const double* a,
                 Work& w);

/// Positions (block by block) and kinematics of the chord system in double at w.sigma, w.sigmaDot; also
/// factorises Phi_u's blocks into w.blockLu for the dual passes. Nothing to do when they are those of the
/// last call; with `anyVelocity` (the mass matrix, which does not depend on the velocities) any sigma' will
/// do.
void chordKinematics(const System& C, double t, Work& w, bool anyVelocity = false);

/// The chord system's kinematics in two directions, sigma_j (0) and sigma'_j (1), into B with nd
/// directions, the two at dy and dv (the others zero). Needs chordKinematics() at the same point (its R
/// gives the positions' derivatives).
template <typename ADT>
void twoDirectionKinematics(const System& C, double t, Work& w, int j, int nd, int dy, int dv,
                            Buffers<ADT>& B);

}  // namespace hindsight::mechanism::detail
