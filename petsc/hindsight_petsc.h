// hindsight's trajectory storage as a PETSc TSTrajectory type, "hindsight" (docs/guides/petsc.md).
//
// An unmodified PETSc TSAdjoint program selects it at run time:
//   -dll_append /path/libhindsight_petsc.so -ts_trajectory_type hindsight
//   -ts_trajectory_hindsight_storage binomial:checkpoints=10
// PETSc opens a -dll_append'ed library and runs its PetscDLLibraryRegister_<basename>() (PETSc 3.18,
// src/sys/dll/dl.c: the file name without "lib" and the suffix, '-' turned into '_'), which registers
// the type. A program linked to the library may call hindsightPetscRegister() instead.
//
// Each rank stores its local part of the solution vector (padded to the largest local part, so every
// rank has the same state size, the same byte counts and hence the same checkpoint schedule); the
// forward steps a strategy asks to recompute are taken by the TS itself (TSStep), collectively.
#pragma once

#include <petscts.h>

#ifdef __cplusplus
#include <hindsight/engine/trajectory_storage.h>
#endif

PETSC_EXTERN PetscErrorCode TSTrajectoryCreate_Hindsight(TSTrajectory tj, TS ts);
/// Registers the type "hindsight" with TSTrajectoryRegister(); idempotent.
PETSC_EXTERN PetscErrorCode hindsightPetscRegister(void);
/// Run by PETSc for -dll_append .../libhindsight_petsc.so.
PETSC_EXTERN PetscErrorCode PetscDLLibraryRegister_hindsight_petsc(void);

#ifdef __cplusplus
namespace hindsight {
namespace petsc {

/// What the last forward/backward pair of a "hindsight" trajectory did on this rank.
struct TrajectoryReport {
  std::string spec;
  StorageCounters counters;              ///< the strategy's own counters (recomputedSteps: its schedule's)
  std::int64_t steps = 0;                ///< N of the last forward sweep
  std::int64_t stateSize = 0;            ///< doubles per stored state (the largest local part over the ranks)
  std::int64_t stageCount = 0;           ///< TSGetStages() count of the TS type
  std::int64_t stageRecomputations = 0;  ///< one-step recomputations for an adjoint step's stage values
  std::int64_t reconstructedStepSizes = 0;  ///< steps whose size was not observed (t_{n+1} - t_n used)
  std::int64_t unreplayedRejections = 0;    ///< recomputed rejected steps the replay did not reproduce
};

/// The report of `tj`, which must be of type "hindsight"; PETSC_ERR_ARG_WRONG otherwise.
PetscErrorCode getTrajectoryReport(TSTrajectory tj, TrajectoryReport* report);

}  // namespace petsc
}  // namespace hindsight
#endif
