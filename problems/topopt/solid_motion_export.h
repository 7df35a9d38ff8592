// The solid member over the motion, for ParaView: a time series (STEM.pvd and one .vtu per frame) of the
// whole body in the global plane of the mechanism, placed by the rigid motion of its frame and deformed
// by its modal coordinates (docs/tutorials/rod_as_solid.md, "The deformed member over the motion").
//
// Kinematics (docs/design.md §11, "FFR invariants in 3-D"): a material point at X (member frame: x from
// A along the chord, y from the mid-height, z from the mid-plane) is at r = R + A(beta) (X + u) with
// u = Phi q the modal displacement and A the rotation about z; R = (x, y) and beta are the member
// frame's pose from the mechanism's position solve. The displacements are millimetres or micrometres
// on a rod of a metre, so they are drawn magnified: u is multiplied by a factor s stated in the file
// names (STEM_x<s>.pvd) and in the name of the point field (displacement_x<s>, the magnified u in the
// global axes, mm). The default s is chosen from the motion: the largest power-of-ten multiple of 1, 2
// or 5 that keeps the largest magnified displacement at or below 5 % of the rod length.
//
// With mid-plane symmetry the half model's nodes are mirrored into the whole body: the node at -z moves
// by (u_x, u_y, -u_z) of its image (the modes are symmetric about the mid-plane).
//
// Frames: `frames` output times equally spaced over [t0, t1]; each frame is the first step of the
// forward sweep at or after its time (the fixed-step grid holds them exactly when the spacing is a
// multiple of the step). The run is a values-only forward sweep of the design: ψ1 is the run's.
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/topopt/geometry_export.h>

#include <string>
#include <vector>

namespace hindsight {

/// The member's motion at a few times of a forward run.
struct MemberMotion {
  std::vector<double> times;  ///< [s]
  Matrix poses;               ///< 3 x frames: x, y [m] of the member frame's origin (joint A), beta [rad]
  Matrix modal;               ///< modes x frames: q
  Matrix modes;               ///< the kept modes on the member's DOFs (PistonRodEvaluation::modes)
  double psi1 = 0.0;          ///< of the run
};

/// Simulates `modelDesign` (the densities the model sees: TopologyOptimizer::modelDesign) with `rod` and
/// records `frames` >= 2 frames equally spaced over [t0, t1]. Throws std::invalid_argument for frames < 2
/// and what PistonRod::evaluate throws.
MemberMotion recordMemberMotion(const PistonRod& rod, ConstVectorRef modelDesign, int frames);

/// The global positions [mm] of the whole body's grid points (writeDensityVtu's order; z from the
/// mid-plane) of the solid `field` (its sizes: the configuration's rod) at `pose` (x, y [m], beta [rad])
/// deformed by scale * modes q (modes on the SolidModel's DOFs, modes.cols() == q.size()). `displacement`,
/// when not null, receives the magnified displacement scale * A(beta) u in the global axes [mm].
/// Throws std::invalid_argument for sizes that do not match the field.
Matrix solidFramePoints(const BoxDensityField& field, ConstMatrixRef modes, ConstVectorRef pose,
                        ConstVectorRef q, double scale, Matrix* displacement = nullptr);

/// The largest displacement |Phi q| [m] over the frames' nodes, and the default magnification for it
/// (the header's rule; 1 for a motion without deformation).
double largestDisplacement(const BoxDensityField& field, const MemberMotion& motion);
double defaultMagnification(double largestDisplacementM, double rodLengthM);

/// The scale factor as it appears in names: "100", "2e+06", "0.5" (%g).
std::string magnificationLabel(double scale);

/// Writes DIRECTORY (created; an existing one is replaced only with `overwrite`) with motion_x\<s\>.pvd and
/// frame_\<k\>.vtu, k = 0000..., each frame the field's densities as cell data on solidFramePoints and the
/// point field displacement_x\<s\>; the .pvd's timesteps are motion.times. Written in a temporary directory
/// next to DIRECTORY and renamed: DIRECTORY is absent or complete. Returns the .pvd's path. Throws
/// std::invalid_argument for scale <= 0 or an existing DIRECTORY without `overwrite`, StorageError for a
/// failed write.
std::string writeSolidMotion(const std::string& directory, const BoxDensityField& field,
                             const MemberMotion& motion, double scale, bool overwrite = false);

}  // namespace hindsight
