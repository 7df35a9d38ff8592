// Configuration of the flexible piston-rod benchmark (docs/design.md §2).
//
// Every number of the benchmark table is a field here with the default of docs/design.md §2, so that a run is
// fully described by one RodConfig. Units are SI (m, kg, s, N/m^2, rad/s). Fields marked [P] in
// docs/design.md §2 come from Held, Knüfer & Seifried (reference/), fields marked [C] are hindsight's
// declared choices.
#pragma once

#include <cmath>

namespace hindsight {
namespace rod {

struct RodConfig {
  // --- FE mesh of the rod (docs/design.md §2: 200 x 12 square 4-node plane-stress elements) [P] ---
  int elementsAlongLength = 200;   ///< nx, element columns along x; >= 3 (two solid end columns).
  int elementsThroughHeight = 12;  ///< ny, element rows along y; even (mid-height nodes needed), >= 2.
  double length = 1.0;             ///< L [m], distance between joints A and B.
  double height = 0.06;            ///< H [m].
  double thickness = 0.01;         ///< t [m], plane-stress thickness (the solid's extent in z).
  /// nz: 0 = the member is the plate (plane-stress Q4, problems/rod/fe_model.h); >= 1 = the solid of
  /// hexahedra with nz element layers through the modelled thickness (problems/rod/solid_member.h) [C].
  int elementsThroughThickness = 0;
  /// Solid only: model the half z >= 0 with u_z = 0 on the mid-plane (problems/rod/solid_model.h) [C].
  bool midPlaneSymmetry = false;

  // --- Material (docs/design.md §2) ---
  double youngsModulus = 0.5e11;  ///< E0 [N/m^2] of solid material [P].
  double density = 8750.0;        ///< rho0 [kg/m^3] of solid material [P].
  double poissonRatio = 0.3;      ///< nu [-], plane stress [C]; in (-1, 0.5).

  // --- SIMP law after Olhoff & Du (2005): E = x^p E0; rho = c x^q rho0 (x < threshold), x rho0 else [P] ---
  double stiffnessPenalty = 3.0;   ///< p >= 1.
  double massLawFactor = 1e5;      ///< c > 0; c * threshold^q must equal threshold (continuity).
  double massLawExponent = 6.0;    ///< q >= 1.
  double massLawThreshold = 0.1;   ///< switch point of the density law, in (0, 1].
  double designLowerBound = 0.01;  ///< xMin, in (0, 1).
  double initialDesign = 0.5;      ///< x0 [C], in [xMin, 1].

  // --- Modal reduction (docs/design.md §2 "shape functions") [C] ---
  int modeCount = 10;               ///< n normal modes kept, >= 1.
  bool inertiaReliefModes = false;  ///< append the 3 static modes K^-1 M [e_x, e_y, S X].

  // --- Mechanism and time horizon (docs/design.md §2) ---
  double crankRadius = 0.15;                          ///< r [m], in (0, L) [C].
  double crankSpeed = 10.0 * 3.14159265358979323846;  ///< Omega [rad/s] after the ramp [C].
  double rampTime = 2.0;                              ///< T [s] of the cycloidal ramp [P].
  double endTime = 3.0;                               ///< t1 [s], >= rampTime [P].
  int eslSamples = 100;                               ///< number of equivalent static load time points [P].

  /// Whether the member is the solid (elementsThroughThickness >= 1) rather than the plate.
  bool isSolid() const { return elementsThroughThickness > 0; }
  /// Number of design variables: the inner (nx - 2) * ny elements of the plate, (nx - 2) * ny * nz of the
  /// solid.
  int designCount() const {
    return (elementsAlongLength - 2) * elementsThroughHeight * (isSolid() ? elementsThroughThickness : 1);
  }

  /// Checks every field against its allowed range.
  /// Throws std::invalid_argument naming the field, its value and the allowed range.
  void validate() const;
};

}  // namespace rod
}  // namespace hindsight
