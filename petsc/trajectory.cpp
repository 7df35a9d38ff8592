// The TSTrajectory type "hindsight" (petsc/hindsight_petsc.h, docs/guides/petsc.md).
//
// How PETSc 3.18 drives a trajectory (src/ts/interface/ts.c TSSolve, sensitivity/tssen.c
// TSAdjointSolve): TSSolve calls set(n, t_n, x_n) for n = 0 and after every accepted step, the last
// time with ts->reason set; TSAdjointSolve calls get(n) for n = N, N-1, ..., 1 (and get(0) once
// when it reaches the start), and after get(n) TSAdjointStep reverses the step n-1 -> n from what
// the TS then holds: the stage vectors of TSGetStages() (RK reads only those; theta reads X0 and
// vec_sol, which are its stages), ts->ptime = t_n and ts->time_step = t_{n-1} - t_n.
//
// hindsight's protocol (engine/trajectory_storage.h) wants record(n, x_n) for n < N, finish(N, x_N),
// then restore(n) for n = N-1, ..., 0. So set(n+1) records x_n (kept since set(n)) together with
// the stage values of step n (in the TS right after that step), and get(n) restores x_{n-1}; the
// stage values of step n-1 come from the strategy when it kept them (stages=1, cams), otherwise
// from one recomputed step x_{n-1} -> x_n, exactly as PETSc's own memory trajectory does in its
// solution-only mode (src/ts/trajectory/impls/memory/trajmemory.c, TSTrajectoryMemoryGet_N). The
// steps a strategy recomputes go through advance(), which takes one TSStep from the restored state
// with the step size the forward sweep took, so the bits are the forward sweep's.
//
// Collective failure. The checkpoint schedule is the same on every rank (states are padded to the
// largest local part), so every rank calls TSStep for the same recomputations. A failure on one rank
// (a full budget, an unreadable file) must not leave the others waiting inside a collective
// TSStep: every set/get ends with one agreement (an MPI_Allreduce of a failure flag) and every
// recomputed step starts with one, so the ranks meet at the same agreement, all learn of the failure,
// and all raise the failing rank's message.
#include <hindsight/petsc/hindsight_petsc.h>

#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/storage_factory.h>

#include <petsc/private/tsimpl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#if !defined(PETSC_USE_REAL_DOUBLE) || defined(PETSC_USE_COMPLEX)
#error \
    "hindsight's PETSc trajectory needs PETSc with real double scalars (Debian's petsc-dev, PETSC_ARCH *-real)"
#endif

namespace hindsight {
namespace petsc {
namespace {

constexpr const char* kOption = "-ts_trajectory_hindsight_storage";

/// Thrown out of a recomputed step when another rank reported a failure at the agreement.
class PeerFailure : public std::runtime_error {
 public:
  PeerFailure() : std::runtime_error("another rank failed") {}
};

/// A PETSc call inside a recomputed step failed (its error was already printed by PETSc).
class PetscCallFailure : public std::runtime_error {
 public:
  PetscCallFailure(const std::string& what, PetscErrorCode code)
      : std::runtime_error(what + " failed with PETSc error " + std::to_string(code)), code_(code) {}
  PetscErrorCode code() const { return code_; }

 private:
  PetscErrorCode code_;
};

void check(PetscErrorCode code, const char* what) {
  if (code) throw PetscCallFailure(what, code);
}

// The step size an adaptive forward step took. After a rejection PETSc retries with a smaller step and
// keeps no record of it; t_{n+1} - t_n is not it in general (t_n + h rounds), and a recomputation with
// a step size one bit off does not reproduce the step. Every attempt passes its step size to the
// adaptor's choose method (src/ts/adapt/interface/tsadapt.c, TSAdaptChoose), so the trajectory wraps
// that method and keeps the last size it saw: the accepted step's.
using ChooseMethod = PetscErrorCode (*)(TSAdapt, TS, PetscReal, PetscInt*, PetscReal*, PetscBool*, PetscReal*,
                                        PetscReal*, PetscReal*);
struct AdaptHook {
  ChooseMethod original = nullptr;
  double lastStepSize = std::numeric_limits<double>::quiet_NaN();
};
std::map<TSAdapt, AdaptHook>& adaptHooks() {
  static std::map<TSAdapt, AdaptHook> hooks;
  return hooks;
}
PetscErrorCode hookedChoose(TSAdapt adapt, TS ts, PetscReal h, PetscInt* scheme, PetscReal* nextH,
                            PetscBool* accept, PetscReal* wlte, PetscReal* wltea, PetscReal* wlter) {
  AdaptHook& hook = adaptHooks()[adapt];
  hook.lastStepSize = h;
  return hook.original(adapt, ts, h, scheme, nextH, accept, wlte, wltea, wlter);
}
/// Installs the wrapper on `adapt` (once; again when the adaptor's type changed) and clears its record.
void hookAdapt(TSAdapt adapt) {
  if (adapt->ops->choose == nullptr) return;
  if (adapt->ops->choose != hookedChoose) adaptHooks()[adapt] = AdaptHook{adapt->ops->choose};
  adapt->ops->choose = hookedChoose;
  adaptHooks()[adapt].lastStepSize = std::numeric_limits<double>::quiet_NaN();
}
/// The step size of the last attempt on `adapt`, NaN when none was seen since hookAdapt().
double lastAttemptedStepSize(TSAdapt adapt) {
  if (!adapt || adapt->ops->choose != hookedChoose) return std::numeric_limits<double>::quiet_NaN();
  return adaptHooks()[adapt].lastStepSize;
}

class Trajectory final : public StepRecomputer {
 public:
  explicit Trajectory(MPI_Comm comm) : comm_(comm) {
    MPI_Comm_rank(comm_, &rank_);
    MPI_Comm_size(comm_, &size_);
  }

  std::string specText = "full";
  std::unique_ptr<TrajectoryStorage> storage;
  TrajectoryReport report;  // of the last completed (or current) run
  bool failed = false;      // a collective failure was raised; the object is unusable until reset
  bool verify = false;      // -ts_trajectory_hindsight_verify

  int rank() const { return rank_; }
  int size() const { return size_; }
  MPI_Comm comm() const { return comm_; }

  /// Creates the strategy from specText; throws std::invalid_argument for a spec that cannot run here.
  void createStorage() {
    const StorageSpec parsed = StorageSpec::parse(specText);
    // "%r" in the spec (dir=/scratch/run/rank%r) becomes the rank, for node-local directories. Files
    // are per rank in any case (disk and multilevel name theirs by process id).
    std::string local = specText;
    for (std::size_t at = local.find("%r"); at != std::string::npos; at = local.find("%r", at)) {
      local.replace(at, 2, std::to_string(rank_));
    }
    std::unique_ptr<TrajectoryStorage> created = hindsight::createStorage(local);
    if (created->needsDerivative()) {
      throw std::invalid_argument(std::string(kOption) + " " + specText +
                                  ": this strategy needs the time derivative at every step, which a "
                                  "TSTrajectory is not given; choose full, binomial, online, cams, packed, "
                                  "disk, lossy or multilevel");
    }
    if (parsed.name() == "multilevel" && !parsed.has("costs") && size_ > 1) {
      throw std::invalid_argument(std::string(kOption) + " " + specText +
                                  ": multilevel measures its cost model at the start of the run, and the "
                                  "measurements differ between ranks, so the ranks would plan different "
                                  "schedules; give costs=uf:ub:wd:rd (seconds) under MPI");
    }
    storage = std::move(created);
    report = TrajectoryReport{};
    report.spec = storage->spec();
  }

  // ---- forward sweep -------------------------------------------------------------------------

  void set(TS ts, PetscInt stepnum, PetscReal time, Vec X) {
    ts_ = ts;
    if (stepnum == 0) {
      start(ts, time, X);
      if (ts->reason) throw std::invalid_argument("TSSolve took no step; nothing to store");
      return;
    }
    if (!running_ || stepnum != static_cast<PetscInt>(times_.size())) {
      throw std::logic_error("TSTrajectorySet(" + std::to_string(stepnum) + ") out of order: expected step " +
                             std::to_string(times_.size()) + " of a forward sweep started at step 0");
    }
    const std::int64_t n = stepnum - 1;  // the step just taken, n -> n+1
    const double t0 = times_.back();
    // The step size the forward sweep took: the last one the adaptor saw (see hookedChoose), or the
    // one the TS held at set(n) when no step was rejected; failing both, t_{n+1} - t_n, which may
    // differ from it in the last bit.
    double h = lastAttemptedStepSize(ts->adapt);
    if (!(std::isfinite(h) && t0 + h == time)) {
      h = pendingStepSize_;
      if (ts->reject != pendingRejects_ || t0 + h != time) {
        h = time - t0;
        ++report.reconstructedStepSizes;
      }
    }
    storage->record(n, t0, pending_, empty_);
    if (stepDataSize_ > 0) {
      gatherStages(stageBuffer_);
      storage->recordStepData(n, stageBuffer_);
    }
    times_.push_back(time);
    stepSizes_.push_back(h);
    firstAttempts_.push_back(std::isfinite(pendingStepSize_) ? pendingStepSize_ : h);
    gather(X, pending_);
    if (ts->reason) {
      const std::int64_t N = stepnum;
      if (predictedSteps_ >= 0 && N != predictedSteps_) {
        throw std::invalid_argument(
            "the TS took " + std::to_string(N) + " steps, but " + std::to_string(predictedSteps_) +
            " were predicted from its final time, step size and -ts_max_steps (fixed steps), and strategy " +
            storage->spec() +
            " needs the number in advance; give -ts_max_steps N (a final time that is a whole number of "
            "steps "
            "may round either way) or use online");
      }
      storage->finish(N, time, pending_, empty_);
      previous_.swap(pending_);  // x_N, the state vec_sol holds at get(N)
      report.steps = N;
      nextGet_ = N;
      running_ = false;
      backward_ = true;
    } else {
      pendingStepSize_ = ts->time_step;
      pendingRejects_ = ts->reject;
    }
  }

  // ---- backward sweep ------------------------------------------------------------------------

  void get(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal* t) {
    ts_ = ts;
    if (!tj->adjoint_solve_mode) {
      throw std::invalid_argument(
          "the hindsight trajectory serves TSAdjointSolve only (states in reverse order); for TSGetVecs or "
          "forward sensitivities use -ts_trajectory_type basic or memory");
    }
    if (!backward_ || stepnum != nextGet_) {
      throw std::logic_error("TSTrajectoryGet(" + std::to_string(stepnum) + ") out of order: expected step " +
                             std::to_string(nextGet_) + " after a forward sweep of " +
                             std::to_string(report.steps) + " steps");
    }
    const TSConvergedReason reason = ts->reason;
    if (stepnum == 0) {  // after the last adjoint step: x_0, for the adjoint monitor
      scatter(previous_, ts->vec_sol);
      *t = times_[0];
      ts->ptime = times_[0];
      backward_ = false;
      report.counters = storage->counters();
      return;
    }
    const std::int64_t n = stepnum;
    storage->restore(n - 1, scratch_);
    bool haveStages = false;
    if (stepDataSize_ > 0) haveStages = storage->restoreStepData(n - 1, stageBuffer_);
    if (haveStages) {
      scatterStages(stageBuffer_);
      scatter(previous_, ts->vec_sol);
    } else if (stageCount_ > 0) {
      step(n - 1, scratch_);  // vec_sol = x_n, the stages of step n-1 in the TS
      ++report.stageRecomputations;
      ++tj->recomps;
    } else {
      scatter(previous_, ts->vec_sol);
    }
    previous_.swap(scratch_);
    ts->steps = stepnum;
    ts->reason = reason;
    ts->ptime = times_[n];
    ts->ptime_prev = times_[n - 1];
    check(TSSetTimeStep(ts, times_[n - 1] - times_[n]), "TSSetTimeStep");  // negative: the adjoint direction
    *t = times_[n];
    nextGet_ = n - 1;
    report.counters = storage->counters();
  }

  // ---- StepRecomputer ------------------------------------------------------------------------

  void advance(std::int64_t stepIndex, VectorRef z) override {
    if (agree(false)) throw PeerFailure();
    const TSConvergedReason reason = ts_->reason;
    step(stepIndex, z);
    ts_->reason = reason;
    gather(ts_->vec_sol, z);
    ++ts_->trajectory->recomps;
  }

  void stepData(VectorRef data) override { gatherStages(data); }

  // ---- collective failure ------------------------------------------------------------------

  /// Every rank calls this at the same points; true when any rank passes true.
  bool agree(bool localFailure) const {
    int mine = localFailure ? 1 : 0;
    int any = 0;
    MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm_);
    return any != 0;
  }

  /// After the ranks agreed on a failure: the lowest failing rank's message, on every rank.
  std::string failureMessage(const std::string& localMessage, bool localFailure) const {
    int candidate = localFailure ? rank_ : size_;
    int origin = size_;
    MPI_Allreduce(&candidate, &origin, 1, MPI_INT, MPI_MIN, comm_);
    char buffer[1024] = {0};
    if (rank_ == origin) std::strncpy(buffer, localMessage.c_str(), sizeof(buffer) - 1);
    MPI_Bcast(buffer, sizeof(buffer), MPI_CHAR, origin, comm_);
    return "hindsight trajectory (" + specText + ") failed on rank " + std::to_string(origin) + " of " +
           std::to_string(size_) + ": " + buffer;
  }

  void reset() {
    running_ = false;
    backward_ = false;
    failed = false;
  }

 private:
  void start(TS ts, PetscReal time, Vec X) {
    PetscInt local = 0;
    check(VecGetLocalSize(X, &local), "VecGetLocalSize");
    long long mine = local;
    long long largest = 0;
    MPI_Allreduce(&mine, &largest, 1, MPI_LONG_LONG, MPI_MAX, comm_);
    localSize_ = local;
    paddedSize_ = static_cast<std::int64_t>(largest);
    check(TSGetStages(ts, &stageCount_, nullptr), "TSGetStages");
    stepDataSize_ = storage->keepsStepData() && stageCount_ > 0 ? stageCount_ * paddedSize_ : 0;

    PetscBool fixed = PETSC_TRUE;
    if (ts->adapt) check(PetscObjectTypeCompare((PetscObject)ts->adapt, TSADAPTNONE, &fixed), "TSAdapt type");
    predictedSteps_ = -1;
    if (!fixed) hookAdapt(ts->adapt);
    if (fixed) {  // as PETSc's memory trajectory predicts it (TSTrajectorySetUp_Memory)
      double byTime = std::ceil((ts->max_time - time) / ts->time_step);
      std::int64_t steps = byTime > 0 && byTime < 1e15 ? static_cast<std::int64_t>(byTime) : PETSC_MAX_INT;
      predictedSteps_ = std::min<std::int64_t>(ts->max_steps, steps);
    }
    TrajectoryInfo info;
    const char* name = nullptr;
    PetscObjectGetName((PetscObject)ts, &name);
    info.problemName = name ? name : "petsc";
    info.stateSize = static_cast<int>(paddedSize_);
    info.t0 = time;
    info.t1 = ts->max_time < 1e300 && ts->max_time > time ? ts->max_time
                                                          : time + std::fabs(ts->time_step) * ts->max_steps;
    if (!(info.t1 > info.t0)) info.t1 = time + 1.0;
    info.stepCount = predictedSteps_;
    info.stepDataSize = stepDataSize_;

    pending_.setZero(paddedSize_);
    previous_.setZero(paddedSize_);
    scratch_.setZero(paddedSize_);
    stageBuffer_.setZero(stepDataSize_ > 0 ? stepDataSize_ : 0);
    times_.assign(1, time);
    stepSizes_.clear();
    firstAttempts_.clear();
    report.steps = 0;
    report.stateSize = paddedSize_;
    report.stageCount = stageCount_;
    report.stageRecomputations = 0;
    report.reconstructedStepSizes = 0;
    report.unreplayedRejections = 0;
    running_ = true;
    backward_ = false;
    storage->setVerifyRestores(verify);
    storage->begin(info, *this);
    gather(X, pending_);
    pendingStepSize_ = ts->time_step;
    pendingRejects_ = ts->reject;
  }

  /// One forward step x_i -> x_{i+1} (vec_sol <- x_{i+1}) from `from` = x_i, as the forward sweep took it.
  void step(std::int64_t i, const Eigen::Ref<const Eigen::VectorXd>& from) {
    const std::size_t k = static_cast<std::size_t>(i);
    // A step the adaptor rejected first is replayed from its first attempt: PETSc's RK rolls a
    // rejected attempt back by subtraction (TSRollBack_RK), so the accepted attempt started from a
    // state a few bits off x_i, and only the same rejection reproduces it. The adaptor decides from
    // the same numbers, so it rejects again; when it does not land on t_{i+1}, the accepted size is
    // taken directly (counted in the view).
    if (firstAttempts_[k] != stepSizes_[k]) {
      attempt(i, from, firstAttempts_[k]);
      if (ts_->ptime == times_[k + 1]) return;
      ++report.unreplayedRejections;
    }
    attempt(i, from, stepSizes_[k]);
  }

  void attempt(std::int64_t i, const Eigen::Ref<const Eigen::VectorXd>& from, double h) {
    TS ts = ts_;
    scatter(from, ts->vec_sol);
    ts->ptime = times_[static_cast<std::size_t>(i)];
    check(TSSetTimeStep(ts, h), "TSSetTimeStep");
    ts->steps = static_cast<PetscInt>(i);
    // A first-same-as-last RK tableau reuses the last stage's right-hand side of the previous step
    // unless the step restarts; that value is stale here, so it is evaluated afresh (which can differ
    // from the forward sweep's in the last bits: docs/guides/petsc.md, "Bitwise equality").
    ts->steprestart = PETSC_TRUE;
    ts->reason = TS_CONVERGED_ITERATING;
    check(TSStep(ts), "TSStep (recomputing a forward step)");
    if (ts->reason < 0) {
      throw std::runtime_error("recomputing step " + std::to_string(i) +
                               " failed: " + TSConvergedReasons[ts->reason]);
    }
  }

  void gather(Vec X, VectorRef z) const {
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(X, &a), "VecGetArrayRead");
    std::copy(a, a + localSize_, z.data());
    check(VecRestoreArrayRead(X, &a), "VecRestoreArrayRead");
  }
  void gather(Vec X, Eigen::VectorXd& z) const { gather(X, VectorRef(z)); }

  void scatter(const Eigen::Ref<const Eigen::VectorXd>& z, Vec X) const {
    PetscScalar* a = nullptr;
    check(VecGetArrayWrite(X, &a), "VecGetArrayWrite");
    std::copy(z.data(), z.data() + localSize_, a);
    check(VecRestoreArrayWrite(X, &a), "VecRestoreArrayWrite");
  }

  void gatherStages(VectorRef data) const {
    Vec* Y = nullptr;
    PetscInt count = 0;
    check(TSGetStages(ts_, &count, &Y), "TSGetStages");
    for (PetscInt i = 0; i < count; ++i) gather(Y[i], data.segment(i * paddedSize_, paddedSize_));
  }
  void gatherStages(Eigen::VectorXd& data) const { gatherStages(VectorRef(data)); }

  void scatterStages(const Eigen::VectorXd& data) const {
    Vec* Y = nullptr;
    PetscInt count = 0;
    check(TSGetStages(ts_, &count, &Y), "TSGetStages");
    for (PetscInt i = 0; i < count; ++i) scatter(data.segment(i * paddedSize_, paddedSize_), Y[i]);
  }

  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
  TS ts_ = nullptr;
  PetscInt localSize_ = 0;
  std::int64_t paddedSize_ = 0;
  PetscInt stageCount_ = 0;
  std::int64_t stepDataSize_ = 0;
  std::int64_t predictedSteps_ = -1;
  Eigen::VectorXd pending_, previous_, scratch_, stageBuffer_;
  const Eigen::VectorXd empty_;
  std::vector<double> times_;          // t_0 .. t_N
  std::vector<double> stepSizes_;      // the step size of step n, n -> n+1
  std::vector<double> firstAttempts_;  // the size step n first tried (larger when it was rejected)
  double pendingStepSize_ = 0.0;
  PetscInt pendingRejects_ = 0;
  bool running_ = false;
  bool backward_ = false;
  std::int64_t nextGet_ = -1;
};

Trajectory& of(TSTrajectory tj) { return *static_cast<Trajectory*>(tj->data); }

/// Runs `body` on every rank of the trajectory and turns an exception on any rank into the same PETSc
/// error on all of them (see the header comment).
template <class Body>
PetscErrorCode collectively(TSTrajectory tj, Body&& body) {
  Trajectory& self = of(tj);
  if (self.failed) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_ARG_WRONGSTATE,
            "hindsight trajectory: an earlier failure left it unusable; call TSTrajectoryReset()");
  }
  bool localFailure = false;
  bool agreed = false;  // the failure is already known to every rank
  std::string message;
  PetscErrorCode code = PETSC_ERR_LIB;
  try {
    body(self);
  } catch (const PeerFailure&) {
    agreed = true;
  } catch (const PetscCallFailure& error) {
    localFailure = true;
    message = error.what();
    code = error.code();
  } catch (const std::invalid_argument& error) {
    localFailure = true;
    message = error.what();
    code = PETSC_ERR_USER_INPUT;
  } catch (const StorageError& error) {
    localFailure = true;
    message = error.what();
    code = PETSC_ERR_FILE_UNEXPECTED;
  } catch (const std::exception& error) {
    localFailure = true;
    message = error.what();
  }
  if (!agreed && !self.agree(localFailure)) return 0;
  self.failed = true;
  const std::string text = self.failureMessage(message, localFailure);
  SETERRQ(PETSC_COMM_SELF, localFailure ? code : PETSC_ERR_LIB, "%s", text.c_str());
}

PetscErrorCode setOp(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal time, Vec X) {
  PetscFunctionBegin;
  PetscCall(collectively(tj, [&](Trajectory& self) { self.set(ts, stepnum, time, X); }));
  PetscFunctionReturn(0);
}

PetscErrorCode getOp(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal* t) {
  PetscFunctionBegin;
  PetscCall(collectively(tj, [&](Trajectory& self) { self.get(tj, ts, stepnum, t); }));
  if (stepnum == 0 && tj->adjoint_solve_mode) {
    // As PETSc's memory trajectory does, so the next TSSolve sets the trajectory up afresh.
    PetscCall(TSTrajectoryReset(tj));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode setupOp(TSTrajectory tj, TS ts) {
  (void)ts;
  PetscFunctionBegin;
  Trajectory& self = of(tj);
  if (!self.storage) {
    try {
      self.createStorage();
    } catch (const std::exception& error) {
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "%s %s: %s", kOption, self.specText.c_str(),
              error.what());
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode setFromOptionsOp(TSTrajectory tj, PetscOptionItems* PetscOptionsObject) {
  PetscFunctionBegin;
  Trajectory& self = of(tj);
  char spec[PETSC_MAX_PATH_LEN] = {0};
  std::strncpy(spec, self.specText.c_str(), sizeof(spec) - 1);
  PetscBool given = PETSC_FALSE;
  PetscOptionsHeadBegin(PetscOptionsObject, "hindsight trajectory options");
  PetscCall(
      PetscOptionsString(kOption,
                         "hindsight storage strategy NAME[:key=value,...]: full, binomial:checkpoints=C, "
                         "online:checkpoints=C, cams:checkpoints=C, packed, disk:dir=D, lossy:..., "
                         "multilevel:ram=R,disk=D,costs=... (docs/guides/petsc.md)",
                         "", spec, spec, sizeof(spec), &given));
  PetscBool verify = self.verify ? PETSC_TRUE : PETSC_FALSE;
  PetscCall(
      PetscOptionsBool("-ts_trajectory_hindsight_verify",
                       "check every restored state (and stage set) against a hash of the recorded bits; a "
                       "difference stops the run",
                       "", verify, &verify, nullptr));
  self.verify = verify == PETSC_TRUE;
  PetscOptionsHeadEnd();
  if (given) {
    self.specText = spec;
    try {
      self.createStorage();
    } catch (const std::exception& error) {
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "%s %s: %s", kOption, spec, error.what());
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode viewOp(TSTrajectory tj, PetscViewer viewer) {
  PetscFunctionBegin;
  Trajectory& self = of(tj);
  const TrajectoryReport& r = self.report;
  const StorageCounters& c = r.counters;
  // Bytes are per rank; the largest over the ranks is the one a memory limit per rank must hold.
  long long local[3] = {static_cast<long long>(c.peakBytesInMemory), static_cast<long long>(c.bytesOnDisk),
                        static_cast<long long>(r.stateSize)};
  long long largest[3] = {0, 0, 0};
  PetscCallMPI(MPI_Allreduce(local, largest, 3, MPI_LONG_LONG, MPI_MAX, self.comm()));
  const long long budget = self.storage ? static_cast<long long>(self.storage->budgetBytes()) : 0;
  PetscCall(PetscViewerASCIIPrintf(viewer, "hindsight storage: %s\n", r.spec.c_str()));
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "steps: %lld, stored state: %lld doubles per rank (largest local part), "
                                   "stages per step: %lld\n",
                                   static_cast<long long>(r.steps), largest[2],
                                   static_cast<long long>(r.stageCount)));
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "recomputed steps: %lld (checkpoint schedule) + %lld (stage values of "
                                   "adjoint steps)\n",
                                   static_cast<long long>(c.recomputedSteps),
                                   static_cast<long long>(r.stageRecomputations)));
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "states stored: %lld, step data stored: %lld, adjoint steps from stored "
                                   "stages: %lld\n",
                                   static_cast<long long>(c.statesStored),
                                   static_cast<long long>(c.stepDataStored),
                                   static_cast<long long>(c.stepDataRestored)));
  PetscCall(PetscViewerASCIIPrintf(
      viewer, "peak bytes in memory: %lld (largest over ranks; budget %lld per rank)\n", largest[0], budget));
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "bytes on disk: %lld (largest over ranks), compression ratio %.3f\n",
                                   largest[1], c.compressionRatio()));
  if (r.reconstructedStepSizes > 0) {
    PetscCall(
        PetscViewerASCIIPrintf(viewer,
                               "steps whose size was not observed: %lld (recomputed with t_{n+1} - t_n, "
                               "possibly a last-bit different step size)\n",
                               static_cast<long long>(r.reconstructedStepSizes)));
  }
  if (r.unreplayedRejections > 0) {
    PetscCall(PetscViewerASCIIPrintf(viewer,
                                     "rejected steps whose replay did not land on the forward time: %lld "
                                     "(retaken with the accepted size)\n",
                                     static_cast<long long>(r.unreplayedRejections)));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode resetOp(TSTrajectory tj) {
  PetscFunctionBegin;
  of(tj).reset();
  PetscFunctionReturn(0);
}

PetscErrorCode destroyOp(TSTrajectory tj) {
  PetscFunctionBegin;
  delete static_cast<Trajectory*>(tj->data);
  tj->data = nullptr;
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode getTrajectoryReport(TSTrajectory tj, TrajectoryReport* report) {
  PetscFunctionBegin;
  PetscBool match = PETSC_FALSE;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, "hindsight", &match));
  PetscCheck(match, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_WRONG,
             "the trajectory is not of type hindsight");
  *report = of(tj).report;
  PetscFunctionReturn(0);
}

}  // namespace petsc
}  // namespace hindsight

PetscErrorCode TSTrajectoryCreate_Hindsight(TSTrajectory tj, TS ts) {
  (void)ts;
  PetscFunctionBegin;
  using namespace hindsight::petsc;
  tj->ops->set = setOp;
  tj->ops->get = getOp;
  tj->ops->setup = setupOp;
  tj->ops->setfromoptions = setFromOptionsOp;
  tj->ops->view = viewOp;
  tj->ops->reset = resetOp;
  tj->ops->destroy = destroyOp;
  tj->data = new Trajectory(PetscObjectComm((PetscObject)tj));
  // Stages are the strategy's business (stages=1, cams); PETSc's own flag only describes its types.
  tj->solution_only = PETSC_TRUE;
  PetscFunctionReturn(0);
}

PetscErrorCode hindsightPetscRegister(void) {
  static bool registered = false;
  PetscFunctionBegin;
  if (registered) PetscFunctionReturn(0);
  PetscCall(TSInitializePackage());
  PetscCall(TSTrajectoryRegister("hindsight", TSTrajectoryCreate_Hindsight));
  registered = true;
  PetscFunctionReturn(0);
}

PetscErrorCode PetscDLLibraryRegister_hindsight_petsc(void) { return hindsightPetscRegister(); }
