#include <hindsight/cvodes/cvodes_adjoint.h>
#include <hindsight/engine/step_controller.h>
#include <hindsight/engine/stopwatch.h>

#include <cvodes/cvodes.h>
#include <cvodes/cvodes_ls.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunlinsol/sunlinsol_spgmr.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <cmath>
#include <cstdlib>
#include <exception>
#include <sstream>
#include <utility>
#include <vector>

namespace hindsight {
namespace {

/// The one owner of SUNDIALS objects (RAII): context, CVODES memory (forward, adjoint and backward),
/// vectors, dense matrices, linear and nonlinear solvers. Nothing outside this class sees an N_Vector.
class CvodesAdjointSolver final {
  // ---- The callbacks SUNDIALS calls, and what they need (user_data). ----
  /// Everything the callbacks need; SUNDIALS hands it back as user_data.
  struct CallbackData {
    const Problem* problem = nullptr;
    Vector p;
    std::unique_ptr<ProblemWorkspace> workspace;
    int n = 0;
    int np = 0;
    Matrix jacobian;             // n x n scratch for F_z (dense paths only)
    bool backwardPhase = false;  // F calls during CVodeB are recomputations
    std::int64_t forwardRhsEvaluations = 0;
    std::int64_t recomputedRhsEvaluations = 0;
    std::int64_t backwardRhsEvaluations = 0;
    std::int64_t backwardQuadratureEvaluations = 0;
    std::int64_t stateVjps = 0;
    std::int64_t jacobianEvaluations = 0;
    std::exception_ptr error;  // first exception thrown by the problem inside a callback
    std::string lastMessage;   // CVODES' error messages, "; "-separated (backward errors come in pairs)
  };

  using ConstMap = Eigen::Map<const Vector>;
  using MutableMap = Eigen::Map<Vector>;

  static ConstMap view(N_Vector v, Eigen::Index size) { return ConstMap(N_VGetArrayPointer(v), size); }
  static MutableMap mutableView(N_Vector v, Eigen::Index size) {
    return MutableMap(N_VGetArrayPointer(v), size);
  }

  /// Runs `body`; an exception is stored (the first one wins) and CVODES gets -1, unrecoverable.
  template <typename Body>
  static int guarded(void* userData, Body&& body) {
    auto* data = static_cast<CallbackData*>(userData);
    try {
      body(*data);
      return 0;
    } catch (...) {
      if (!data->error) data->error = std::current_exception();
      return -1;
    }
  }

  // ---- Forward problem: z' = F, q' = G. ----

  static int forwardRhs(realtype t, N_Vector z, N_Vector zdot, void* userData) {
    return guarded(userData, [&](CallbackData& d) {
      ++(d.backwardPhase ? d.recomputedRhsEvaluations : d.forwardRhsEvaluations);
      MutableMap f = mutableView(zdot, d.n);
      d.problem->rhs(t, view(z, d.n), d.p, f, d.workspace.get());
    });
  }

  static int forwardQuadrature(realtype t, N_Vector z, N_Vector qdot, void* userData) {
    return guarded(userData, [&](CallbackData& d) {
      NV_Ith_S(qdot, 0) = d.problem->integrand(t, view(z, d.n), d.p, d.workspace.get());
    });
  }

  static int forwardJacobian(realtype t, N_Vector z, N_Vector, SUNMatrix jacobian, void* userData, N_Vector,
                             N_Vector, N_Vector) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.jacobianEvaluations;
      Eigen::Map<Matrix> j(SUNDenseMatrix_Data(jacobian), d.n, d.n);  // column-major, like Eigen
      d.problem->rhsJacobian(t, view(z, d.n), d.p, j, d.workspace.get());
    });
  }

  // ---- Backward problem: lambda' = -F_z^T lambda - G_z^T, qB' = -(G_p + F_p^T lambda). ----

  /// F_z^T lambda by the problem's vector-Jacobian product: no Jacobian is formed.
  static int backwardRhsVjp(realtype t, N_Vector z, N_Vector lambda, N_Vector lambdaDot, void* userData) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.backwardRhsEvaluations;
      ++d.stateVjps;
      const ConstMap zv = view(z, d.n);
      MutableMap out = mutableView(lambdaDot, d.n);
      d.problem->rhsStateVjp(t, zv, d.p, view(lambda, d.n), out, d.workspace.get());
      out = -out;
      d.problem->addIntegrandStateGradient(t, zv, d.p, -1.0, out, d.workspace.get());
    });
  }

  /// F_z^T lambda from the dense Jacobian, for problems without a vector-Jacobian product.
  static int backwardRhsDense(realtype t, N_Vector z, N_Vector lambda, N_Vector lambdaDot, void* userData) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.backwardRhsEvaluations;
      ++d.jacobianEvaluations;
      const ConstMap zv = view(z, d.n);
      d.problem->rhsJacobian(t, zv, d.p, d.jacobian, d.workspace.get());
      MutableMap out = mutableView(lambdaDot, d.n);
      out.noalias() = -(d.jacobian.transpose() * view(lambda, d.n));
      d.problem->addIntegrandStateGradient(t, zv, d.p, -1.0, out, d.workspace.get());
    });
  }

  /// GMRES's product with the backward Jacobian: Jv = d(lambda')/d(lambda) v = -F_z^T v.
  static int backwardJacobianTimesVector(N_Vector v, N_Vector jv, realtype t, N_Vector z, N_Vector, N_Vector,
                                         void* userData, N_Vector) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.stateVjps;
      MutableMap out = mutableView(jv, d.n);
      d.problem->rhsStateVjp(t, view(z, d.n), d.p, view(v, d.n), out, d.workspace.get());
      out = -out;
    });
  }

  static int backwardQuadrature(realtype t, N_Vector z, N_Vector lambda, N_Vector qdot, void* userData) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.backwardQuadratureEvaluations;
      const ConstMap zv = view(z, d.n);
      MutableMap out = mutableView(qdot, d.np);
      out.setZero();
      d.problem->addRhsParameterVjp(t, zv, d.p, view(lambda, d.n), out, d.workspace.get());
      d.problem->addIntegrandParameterGradient(t, zv, d.p, 1.0, out, d.workspace.get());
      out = -out;
    });
  }

  static int backwardJacobian(realtype t, N_Vector z, N_Vector, N_Vector, SUNMatrix jacobian, void* userData,
                              N_Vector, N_Vector, N_Vector) {
    return guarded(userData, [&](CallbackData& d) {
      ++d.jacobianEvaluations;
      d.problem->rhsJacobian(t, view(z, d.n), d.p, d.jacobian, d.workspace.get());
      Eigen::Map<Matrix>(SUNDenseMatrix_Data(jacobian), d.n, d.n) = -d.jacobian.transpose();
    });
  }

  static void errorHandler(int errorCode, const char* module, const char* function, char* message,
                           void* userData) {
    // Warnings (CV_WARNING) do not stop CVODES; only errors go into the next exception's message.
    if (errorCode < 0) {
      auto* data = static_cast<CallbackData*>(userData);
      if (!data->lastMessage.empty()) data->lastMessage += "; ";
      data->lastMessage += std::string(module) + "::" + function + ": " + message;
    }
  }

 public:
  CvodesAdjointSolver(const Problem& problem, ConstVectorRef p, const CvodesOptions& options)
      : options_(options) {
    data_.problem = &problem;
    data_.p = p;
    data_.workspace = problem.createWorkspace();
    data_.n = problem.stateSize();
    data_.np = problem.parameterSize();
    if (problem.hasDenseJacobian()) data_.jacobian = Matrix::Zero(data_.n, data_.n);
    fixedPoint_ =
        options.nonlinearSolver == CvodesNonlinearSolver::FixedPoint ||
        (options.nonlinearSolver == CvodesNonlinearSolver::Auto && options.method == CvodesMethod::Adams);
    gmres_ = options.linearSolver == CvodesLinearSolver::Gmres ||
             (options.linearSolver == CvodesLinearSolver::Auto && !problem.hasDenseJacobian());
    vjp_ = options.backwardProducts == CvodesBackwardProducts::Vjp ||
           (options.backwardProducts == CvodesBackwardProducts::Auto && problem.hasStateVjp());
    if (SUNContext_Create(nullptr, &context_) != 0)
      throw NumericalError("SUNContext_Create failed", options.t0);
    z_ = newVector(data_.n);
    quadrature_ = newVector(1);
    lambda_ = newVector(data_.n);
    gradientQuadrature_ = newVector(data_.np);
  }

  ~CvodesAdjointSolver() {
    if (memory_ != nullptr) CVodeFree(&memory_);  // also frees the adjoint and backward memories
    for (SUNLinearSolver solver : {solver_, solverB_}) {
      if (solver != nullptr) SUNLinSolFree(solver);
    }
    for (SUNNonlinearSolver solver : {nonlinear_, nonlinearB_}) {
      if (solver != nullptr) SUNNonlinSolFree(solver);
    }
    for (SUNMatrix matrix : {matrix_, matrixB_}) {
      if (matrix != nullptr) SUNMatDestroy(matrix);
    }
    for (N_Vector vector : vectors_) N_VDestroy(vector);
    if (context_ != nullptr) SUNContext_Free(&context_);
  }
  CvodesAdjointSolver(const CvodesAdjointSolver&) = delete;
  CvodesAdjointSolver& operator=(const CvodesAdjointSolver&) = delete;

  /// CVodeF from t0 to t1 in one-step mode (to record the grid), storing check points every Nd steps.
  void forward(GradientResult& result) {
    const int lmm = options_.method == CvodesMethod::Bdf ? CV_BDF : CV_ADAMS;
    memory_ = CVodeCreate(lmm, context_);
    if (memory_ == nullptr) throw NumericalError("CVodeCreate failed", options_.t0);
    check(CVodeSetErrHandlerFn(memory_, &errorHandler, &data_), "CVodeSetErrHandlerFn", options_.t0);
    MutableMap z = mutableView(z_, data_.n);
    data_.problem->initialState(data_.p, z);
    for (int k = 0; k < data_.n; ++k) {
      if (!std::isfinite(z(k))) {
        throw std::invalid_argument("initial state z0 of '" + data_.problem->name() +
                                    "' has a non-finite entry z0[" + std::to_string(k) +
                                    "] = " + std::to_string(z(k)));
      }
    }
    check(CVodeInit(memory_, &forwardRhs, options_.t0, z_), "CVodeInit", options_.t0);
    check(CVodeSetUserData(memory_, &data_), "CVodeSetUserData", options_.t0);
    if (options_.absoluteTolerances.empty()) {
      check(CVodeSStolerances(memory_, options_.relativeTolerance, options_.absoluteTolerance),
            "CVodeSStolerances", options_.t0);
    } else {
      check(CVodeSVtolerances(memory_, options_.relativeTolerance,
                              toleranceVector(options_.absoluteTolerances)),
            "CVodeSVtolerances", options_.t0);
    }
    check(CVodeSetMaxNumSteps(memory_, static_cast<long>(options_.maxSteps)), "CVodeSetMaxNumSteps",
          options_.t0);
    if (options_.initialStep > 0.0) {
      check(CVodeSetInitStep(memory_, options_.initialStep), "CVodeSetInitStep", options_.t0);
    }
    check(CVodeSetStopTime(memory_, options_.t1), "CVodeSetStopTime", options_.t0);
    if (fixedPoint_) {
      nonlinear_ = SUNNonlinSol_FixedPoint(z_, options_.fixedPointAcceleration, context_);
      if (nonlinear_ == nullptr) throw NumericalError("SUNNonlinSol_FixedPoint failed", options_.t0);
      check(CVodeSetNonlinearSolver(memory_, nonlinear_), "CVodeSetNonlinearSolver", options_.t0);
    } else if (gmres_) {
      // Matrix-free Newton: the forward Jacobian-times-vector is CVODES' difference quotient of F.
      solver_ = SUNLinSol_SPGMR(z_, SUN_PREC_NONE, 0, context_);
      if (solver_ == nullptr) throw NumericalError("SUNLinSol_SPGMR failed", options_.t0);
      checkLinear(CVodeSetLinearSolver(memory_, solver_, nullptr), "CVodeSetLinearSolver", options_.t0);
    } else {
      matrix_ = SUNDenseMatrix(data_.n, data_.n, context_);
      solver_ = SUNLinSol_Dense(z_, matrix_, context_);
      if (matrix_ == nullptr || solver_ == nullptr)
        throw NumericalError("dense linear solver creation failed", 0);
      checkLinear(CVodeSetLinearSolver(memory_, solver_, matrix_), "CVodeSetLinearSolver", options_.t0);
      checkLinear(CVodeSetJacFn(memory_, &forwardJacobian), "CVodeSetJacFn", options_.t0);
    }

    N_VConst(0.0, quadrature_);
    check(CVodeQuadInit(memory_, &forwardQuadrature, quadrature_), "CVodeQuadInit", options_.t0);
    check(CVodeQuadSStolerances(memory_,
                                orDefault(options_.quadratureRelativeTolerance, options_.relativeTolerance),
                                orDefault(options_.quadratureAbsoluteTolerance, options_.absoluteTolerance)),
          "CVodeQuadSStolerances", options_.t0);
    check(CVodeSetQuadErrCon(memory_, options_.quadratureErrorControl ? SUNTRUE : SUNFALSE),
          "CVodeSetQuadErrCon", options_.t0);
    check(CVodeAdjInit(memory_, static_cast<long>(options_.checkpointSteps),
                       options_.interpolation == CvodesInterpolation::Hermite ? CV_HERMITE : CV_POLYNOMIAL),
          "CVodeAdjInit", options_.t0);

    result.times.assign(1, options_.t0);
    double t = options_.t0;
    int checkpoints = 0;
    // One-step mode records the grid; CVODES applies mxstep per call, so in this mode the limit on
    // the forward steps is enforced here, with the flag CVODES gives in normal mode.
    while (t < options_.t1) {
      if (static_cast<std::int64_t>(result.times.size()) > options_.maxSteps) {
        check(CV_TOO_MUCH_WORK, "CVodeF", t,
              "more than CvodesOptions.maxSteps = " + std::to_string(options_.maxSteps) + " forward steps");
      }
      const int flag = CVodeF(memory_, options_.t1, z_, &t, CV_ONE_STEP, &checkpoints);
      check(flag, "CVodeF", currentTime(memory_, t));
      result.times.push_back(t);
    }
    double tq = 0.0;
    check(CVodeGetQuad(memory_, &tq, quadrature_), "CVodeGetQuad", t);
    finalState_ = view(z_, data_.n);
    result.objective = NV_Ith_S(quadrature_, 0) + data_.problem->terminal(finalState_, data_.p);

    long steps = 0;
    check(CVodeGetNumSteps(memory_, &steps), "CVodeGetNumSteps", t);
    result.summary.steps = steps;
    addWork(memory_, t, result.summary, forwardWork_);
    result.summary.statesStored = checkpoints;
    // Check points are listed newest first; CVodeB re-integrates every step before the last one.
    std::vector<CVadjCheckPointRec> records(static_cast<std::size_t>(checkpoints) + 2);
    check(CVodeGetAdjCheckPointsInfo(memory_, records.data()), "CVodeGetAdjCheckPointsInfo", t);
    result.summary.recomputedSteps = records.front().nstep;
  }

  /// CVodeB from t1 to t0: lambda and the gradient quadrature; adds the terminal and initial terms.
  void backward(GradientResult& result) {
    const double t1 = options_.t1;
    const int lmm = options_.method == CvodesMethod::Bdf ? CV_BDF : CV_ADAMS;
    int which = 0;
    check(CVodeCreateB(memory_, lmm, &which), "CVodeCreateB", t1);
    Vector gradient = Vector::Zero(data_.np);
    {
      MutableMap lambda = mutableView(lambda_, data_.n);
      lambda.setZero();
      data_.problem->addTerminalGradient(finalState_, data_.p, lambda, gradient);  // lambda(t1) = dphi/dz
    }
    check(CVodeInitB(memory_, which, vjp_ ? &backwardRhsVjp : &backwardRhsDense, t1, lambda_), "CVodeInitB",
          t1);
    void* backwardMemory = CVodeGetAdjCVodeBmem(memory_, which);
    if (backwardMemory == nullptr) throw NumericalError("CVodeGetAdjCVodeBmem returned null", t1);
    check(CVodeSetErrHandlerFn(backwardMemory, &errorHandler, &data_), "CVodeSetErrHandlerFn", t1);
    const double backwardRtol = orDefault(options_.backwardRelativeTolerance, options_.relativeTolerance);
    const double backwardAtol = orDefault(options_.backwardAbsoluteTolerance, options_.absoluteTolerance);
    if (options_.backwardAbsoluteTolerances.empty()) {
      check(CVodeSStolerancesB(memory_, which, backwardRtol, backwardAtol), "CVodeSStolerancesB", t1);
    } else {
      check(CVodeSVtolerancesB(memory_, which, backwardRtol,
                               toleranceVector(options_.backwardAbsoluteTolerances)),
            "CVodeSVtolerancesB", t1);
    }
    check(CVodeSetUserDataB(memory_, which, &data_), "CVodeSetUserDataB", t1);
    check(CVodeSetMaxNumStepsB(memory_, which, static_cast<long>(options_.maxSteps)), "CVodeSetMaxNumStepsB",
          t1);
    if (fixedPoint_) {
      nonlinearB_ = SUNNonlinSol_FixedPoint(lambda_, options_.fixedPointAcceleration, context_);
      if (nonlinearB_ == nullptr) throw NumericalError("SUNNonlinSol_FixedPoint failed", t1);
      check(CVodeSetNonlinearSolverB(memory_, which, nonlinearB_), "CVodeSetNonlinearSolverB", t1);
    } else if (gmres_) {
      solverB_ = SUNLinSol_SPGMR(lambda_, SUN_PREC_NONE, 0, context_);
      if (solverB_ == nullptr) throw NumericalError("SUNLinSol_SPGMR failed", t1);
      checkLinear(CVodeSetLinearSolverB(memory_, which, solverB_, nullptr), "CVodeSetLinearSolverB", t1);
      // -F_z^T v is the problem's own product; without one, CVODES' difference quotient of lambda'.
      if (vjp_) {
        checkLinear(CVodeSetJacTimesB(memory_, which, nullptr, &backwardJacobianTimesVector),
                    "CVodeSetJacTimesB", t1);
      }
    } else {
      // The Newton matrix I - gamma (-F_z^T) needs the Jacobian itself: formed at the setups only.
      matrixB_ = SUNDenseMatrix(data_.n, data_.n, context_);
      solverB_ = SUNLinSol_Dense(lambda_, matrixB_, context_);
      if (matrixB_ == nullptr || solverB_ == nullptr)
        throw NumericalError("dense linear solver creation failed", t1);
      checkLinear(CVodeSetLinearSolverB(memory_, which, solverB_, matrixB_), "CVodeSetLinearSolverB", t1);
      checkLinear(CVodeSetJacFnB(memory_, which, &backwardJacobian), "CVodeSetJacFnB", t1);
    }
    N_VConst(0.0, gradientQuadrature_);
    check(CVodeQuadInitB(memory_, which, &backwardQuadrature, gradientQuadrature_), "CVodeQuadInitB", t1);
    check(CVodeQuadSStolerancesB(memory_, which,
                                 orDefault(options_.backwardQuadratureRelativeTolerance, backwardRtol),
                                 orDefault(options_.backwardQuadratureAbsoluteTolerance, backwardAtol)),
          "CVodeQuadSStolerancesB", t1);
    check(CVodeSetQuadErrConB(memory_, which, options_.quadratureErrorControl ? SUNTRUE : SUNFALSE),
          "CVodeSetQuadErrConB", t1);

    data_.backwardPhase = true;
    const int flag = CVodeB(memory_, options_.t0, CV_NORMAL);
    check(flag, "CVodeB", currentTime(backwardMemory, t1));
    double tB = t1;
    check(CVodeGetB(memory_, which, &tB, lambda_), "CVodeGetB", t1);
    check(CVodeGetQuadB(memory_, which, &tB, gradientQuadrature_), "CVodeGetQuadB", tB);
    gradient += view(gradientQuadrature_, data_.np);
    data_.problem->addInitialStateVjp(data_.p, view(lambda_, data_.n), gradient);
    result.gradient = std::move(gradient);

    addWork(backwardMemory, tB, result.summary, backwardWork_);
  }

  std::int64_t rhsEvaluations() const { return data_.forwardRhsEvaluations + data_.recomputedRhsEvaluations; }
  std::int64_t jacobianEvaluations() const { return data_.jacobianEvaluations; }

  CvodesCounters counters() const {
    CvodesCounters c;
    c.nonlinearSolver = fixedPoint_ ? "fixed-point" : "newton";
    c.linearSolver = fixedPoint_ ? "none" : gmres_ ? "gmres" : "dense";
    c.backwardProducts = vjp_ ? "vjp" : "dense";
    c.forwardRhsEvaluations = data_.forwardRhsEvaluations;
    c.recomputedRhsEvaluations = data_.recomputedRhsEvaluations;
    c.backwardRhsEvaluations = data_.backwardRhsEvaluations;
    c.backwardQuadratureEvaluations = data_.backwardQuadratureEvaluations;
    c.stateVjps = data_.stateVjps;
    c.denseJacobians = data_.jacobianEvaluations;
    c.forwardNonlinearIterations = forwardWork_.iterations;
    c.backwardNonlinearIterations = backwardWork_.iterations;
    c.forwardLinearIterations = forwardWork_.linearIterations;
    c.backwardLinearIterations = backwardWork_.linearIterations;
    c.forwardConvergenceFailures = forwardWork_.convergenceFailures;
    c.backwardConvergenceFailures = backwardWork_.convergenceFailures;
    return c;
  }

 private:
  N_Vector newVector(int size) {
    N_Vector v = N_VNew_Serial(size, context_);
    if (v == nullptr) throw std::bad_alloc();
    vectors_.push_back(v);
    N_VConst(0.0, v);
    return v;
  }

  /// An N_Vector holding `values` (CVODES copies the absolute tolerances it is given).
  N_Vector toleranceVector(const std::vector<double>& values) {
    N_Vector v = newVector(static_cast<int>(values.size()));
    mutableView(v, static_cast<Eigen::Index>(values.size())) =
        Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size()));
    return v;
  }

  /// A tolerance field left at 0 takes the tolerance it defaults to (see CvodesOptions).
  static double orDefault(double value, double fallback) { return value > 0.0 ? value : fallback; }

  /// One CVODES memory's nonlinear and linear work.
  struct Work {
    long iterations = 0, convergenceFailures = 0, linearIterations = 0;
  };

  /// Adds one CVODES memory's rejected steps (error-test and nonlinear convergence failures), linear
  /// solver setups and nonlinear iterations to the summary; keeps them, with the GMRES iterations, in
  /// `work`.
  void addWork(void* memory, double t, RunSummary& summary, Work& work) {
    long errorTestFailures = 0, setups = 0;
    check(CVodeGetNumErrTestFails(memory, &errorTestFailures), "CVodeGetNumErrTestFails", t);
    check(CVodeGetNumNonlinSolvConvFails(memory, &work.convergenceFailures), "CVodeGetNumNonlinSolvConvFails",
          t);
    check(CVodeGetNumLinSolvSetups(memory, &setups), "CVodeGetNumLinSolvSetups", t);
    check(CVodeGetNumNonlinSolvIters(memory, &work.iterations), "CVodeGetNumNonlinSolvIters", t);
    if (!fixedPoint_ && gmres_) {
      checkLinear(CVodeGetNumLinIters(memory, &work.linearIterations), "CVodeGetNumLinIters", t);
    }
    summary.rejectedSteps += errorTestFailures + work.convergenceFailures;
    summary.factorizations += setups;
    summary.newtonIterations += work.iterations;
  }

  static double currentTime(void* memory, double fallback) {
    double t = fallback;
    if (memory != nullptr && CVodeGetCurrentTime(memory, &t) != CV_SUCCESS) t = fallback;
    return t;
  }

  /// A flag < 0 becomes a NumericalError naming the call and the flag; a problem's exception thrown
  /// inside a callback is rethrown as it was.
  void check(int flag, const char* call, double t, std::string detail = {}) {
    if (flag >= 0) return;
    fail(flag, CVodeGetReturnFlagName(flag), call, t, std::move(detail));
  }
  /// The same for the CVLS linear-solver interface, whose flags (CVLS_*) have their own names.
  void checkLinear(int flag, const char* call, double t) {
    if (flag >= 0) return;
    fail(flag, CVodeGetLinReturnFlagName(flag), call, t, {});
  }
  /// Takes ownership of `name` (SUNDIALS allocates it with malloc).
  [[noreturn]] void fail(int flag, char* name, const char* call, double t, std::string detail) {
    if (data_.error) {
      std::free(name);
      std::rethrow_exception(data_.error);
    }
    if (!detail.empty()) data_.lastMessage = std::move(detail);
    std::string message = std::string(call) + " failed with " + (name != nullptr ? name : "an unknown flag") +
                          " (" + std::to_string(flag) + ")";
    std::free(name);
    if (!data_.lastMessage.empty()) message += ": " + data_.lastMessage;
    throw NumericalError(message, t);
  }

  CvodesOptions options_;
  CallbackData data_;
  SUNContext context_ = nullptr;
  void* memory_ = nullptr;
  SUNMatrix matrix_ = nullptr, matrixB_ = nullptr;
  SUNLinearSolver solver_ = nullptr, solverB_ = nullptr;
  SUNNonlinearSolver nonlinear_ = nullptr, nonlinearB_ = nullptr;
  bool fixedPoint_ = false;  // SUNNonlinSol_FixedPoint instead of CVODES' default Newton
  bool gmres_ = false;       // Newton with SUNLinSol_SPGMR instead of SUNLinSol_Dense
  bool vjp_ = false;         // backward rhs by rhsStateVjp()
  Work forwardWork_, backwardWork_;
  std::vector<N_Vector> vectors_;
  N_Vector z_ = nullptr, quadrature_ = nullptr, lambda_ = nullptr, gradientQuadrature_ = nullptr;
  Vector finalState_;
};

}  // namespace

CvodesMethod parseCvodesMethod(const std::string& name) {
  if (name == "bdf") return CvodesMethod::Bdf;
  if (name == "adams") return CvodesMethod::Adams;
  throw std::invalid_argument("CvodesOptions.method = '" + name + "' is unknown; valid: bdf, adams");
}

CvodesInterpolation parseCvodesInterpolation(const std::string& name) {
  if (name == "hermite") return CvodesInterpolation::Hermite;
  if (name == "polynomial") return CvodesInterpolation::Polynomial;
  throw std::invalid_argument("CvodesOptions.interpolation = '" + name +
                              "' is unknown; valid: hermite, polynomial");
}

CvodesNonlinearSolver parseCvodesNonlinearSolver(const std::string& name) {
  if (name == "auto") return CvodesNonlinearSolver::Auto;
  if (name == "newton") return CvodesNonlinearSolver::Newton;
  if (name == "fixed-point") return CvodesNonlinearSolver::FixedPoint;
  throw std::invalid_argument("CvodesOptions.nonlinearSolver = '" + name +
                              "' is unknown; valid: auto, newton, fixed-point");
}

CvodesLinearSolver parseCvodesLinearSolver(const std::string& name) {
  if (name == "auto") return CvodesLinearSolver::Auto;
  if (name == "dense") return CvodesLinearSolver::Dense;
  if (name == "gmres") return CvodesLinearSolver::Gmres;
  throw std::invalid_argument("CvodesOptions.linearSolver = '" + name +
                              "' is unknown; valid: auto, dense, gmres");
}

CvodesBackwardProducts parseCvodesBackwardProducts(const std::string& name) {
  if (name == "auto") return CvodesBackwardProducts::Auto;
  if (name == "vjp") return CvodesBackwardProducts::Vjp;
  if (name == "dense") return CvodesBackwardProducts::Dense;
  throw std::invalid_argument("CvodesOptions.backwardProducts = '" + name +
                              "' is unknown; valid: auto, vjp, dense");
}

std::string toString(CvodesMethod method) { return method == CvodesMethod::Bdf ? "bdf" : "adams"; }

std::string toString(CvodesNonlinearSolver solver) {
  switch (solver) {
    case CvodesNonlinearSolver::Auto:
      return "auto";
    case CvodesNonlinearSolver::Newton:
      return "newton";
    case CvodesNonlinearSolver::FixedPoint:
      return "fixed-point";
  }
  return "unknown";
}

std::string toString(CvodesLinearSolver solver) {
  switch (solver) {
    case CvodesLinearSolver::Auto:
      return "auto";
    case CvodesLinearSolver::Dense:
      return "dense";
    case CvodesLinearSolver::Gmres:
      return "gmres";
  }
  return "unknown";
}

std::string toString(CvodesBackwardProducts products) {
  switch (products) {
    case CvodesBackwardProducts::Auto:
      return "auto";
    case CvodesBackwardProducts::Vjp:
      return "vjp";
    case CvodesBackwardProducts::Dense:
      return "dense";
  }
  return "unknown";
}

std::string toString(CvodesInterpolation interpolation) {
  return interpolation == CvodesInterpolation::Hermite ? "hermite" : "polynomial";
}

bool CvodesOptions::IsValid(std::string* error) const {
  std::ostringstream msg;
  const auto fail = [&]() {
    if (error != nullptr) *error = msg.str();
    return false;
  };
  if (!std::isfinite(t0) || !std::isfinite(t1) || !(t1 > t0)) {
    msg << "CvodesOptions: t1 = " << t1 << " must be finite and greater than t0 = " << t0;
    return fail();
  }
  if (!(relativeTolerance >= 1e-14 && relativeTolerance < 1.0)) {
    msg << "CvodesOptions.relativeTolerance = " << relativeTolerance << " must be in [1e-14, 1)";
    return fail();
  }
  if (!(absoluteTolerance > 0.0) || !std::isfinite(absoluteTolerance)) {
    msg << "CvodesOptions.absoluteTolerance = " << absoluteTolerance << " must be positive and finite";
    return fail();
  }
  // The optional tolerances: 0 means "as the one it defaults to" (see the header).
  struct Optional {
    const char* name;
    double value;
    bool relative;
  };
  const Optional optional[] = {
      {"quadratureRelativeTolerance", quadratureRelativeTolerance, true},
      {"quadratureAbsoluteTolerance", quadratureAbsoluteTolerance, false},
      {"backwardRelativeTolerance", backwardRelativeTolerance, true},
      {"backwardAbsoluteTolerance", backwardAbsoluteTolerance, false},
      {"backwardQuadratureRelativeTolerance", backwardQuadratureRelativeTolerance, true},
      {"backwardQuadratureAbsoluteTolerance", backwardQuadratureAbsoluteTolerance, false}};
  for (const Optional& o : optional) {
    const bool valid = o.value == 0.0 || (o.relative ? o.value >= 1e-14 && o.value < 1.0
                                                     : o.value > 0.0 && std::isfinite(o.value));
    if (!valid) {
      msg << "CvodesOptions." << o.name << " = " << o.value << " must be 0 (the default) or "
          << (o.relative ? "in [1e-14, 1)" : "positive and finite");
      return fail();
    }
  }
  const std::pair<const char*, const std::vector<double>*> vectors[] = {
      {"absoluteTolerances", &absoluteTolerances},
      {"backwardAbsoluteTolerances", &backwardAbsoluteTolerances}};
  for (const auto& [name, values] : vectors) {
    if (const std::string entry = invalidToleranceEntry(*values, std::string("CvodesOptions.") + name);
        !entry.empty()) {
      msg << entry;
      return fail();
    }
  }
  if (checkpointSteps < 1 || checkpointSteps > 1'000'000'000) {
    msg << "CvodesOptions.checkpointSteps = " << checkpointSteps << " must be in [1, 1e9]";
    return fail();
  }
  if (maxSteps < 1 || maxSteps > 1'000'000'000'000) {
    msg << "CvodesOptions.maxSteps = " << maxSteps << " must be in [1, 1e12]";
    return fail();
  }
  if (!(initialStep >= 0.0) || !(initialStep <= t1 - t0)) {
    msg << "CvodesOptions.initialStep = " << initialStep << " must be in [0, t1 - t0 = " << t1 - t0 << "]";
    return fail();
  }
  if (fixedPointAcceleration < 0 || fixedPointAcceleration > 20) {
    msg << "CvodesOptions.fixedPointAcceleration = " << fixedPointAcceleration << " must be in [0, 20]";
    return fail();
  }
  return true;
}

void CvodesOptions::validate() const {
  std::string error;
  if (!IsValid(&error)) throw std::invalid_argument(error);
}

GradientResult computeGradientCvodes(const Problem& problem, ConstVectorRef p, const CvodesOptions& options,
                                     CvodesCounters* counters) {
  options.validate();
  if (p.size() != problem.parameterSize()) {
    throw std::invalid_argument("parameter vector p has size " + std::to_string(p.size()) + " but '" +
                                problem.name() + "' expects " + std::to_string(problem.parameterSize()));
  }
  for (const auto& [name, values] :
       {std::make_pair("absoluteTolerances", &options.absoluteTolerances),
        std::make_pair("backwardAbsoluteTolerances", &options.backwardAbsoluteTolerances)}) {
    requireOneTolerancePerState(*values, std::string("CvodesOptions.") + name, problem.name(),
                                problem.stateSize(), "one atol per state, or empty");
  }
  const bool newton =
      options.nonlinearSolver == CvodesNonlinearSolver::Newton ||
      (options.nonlinearSolver == CvodesNonlinearSolver::Auto && options.method == CvodesMethod::Bdf);
  if (!problem.hasDenseJacobian()) {
    const auto refuse = [&](const std::string& field) {
      throw std::invalid_argument(
          "CvodesOptions." + field + " needs a dense Jacobian, but problem '" + problem.name() +
          "' has hasDenseJacobian() == false; use " +
          (field == "linearSolver" ? "gmres, auto or the fixed-point solver" : "vjp or auto"));
    };
    if (newton && options.linearSolver == CvodesLinearSolver::Dense) refuse("linearSolver");
    if (options.backwardProducts == CvodesBackwardProducts::Dense) refuse("backwardProducts");
  }
  if (options.backwardProducts == CvodesBackwardProducts::Vjp && !problem.hasStateVjp()) {
    throw std::invalid_argument("CvodesOptions.backwardProducts = vjp, but problem '" + problem.name() +
                                "' has no rhsStateVjp() (hasStateVjp() == false); use dense or auto");
  }
  GradientResult result;
  result.summary.method = "cvodes-" + toString(options.method);
  result.summary.adjoint = "cvodes";
  result.summary.storage = "cvodes:checkpoints=" + std::to_string(options.checkpointSteps) +
                           ",interp=" + toString(options.interpolation);
  CvodesAdjointSolver solver(problem, p, options);
  const Stopwatch forwardTimer;
  solver.forward(result);
  result.summary.forwardSeconds = forwardTimer.seconds();
  const Stopwatch backwardTimer;
  solver.backward(result);
  result.summary.backwardSeconds = backwardTimer.seconds();
  result.summary.rhsEvaluations = solver.rhsEvaluations();
  result.summary.jacobianEvaluations = solver.jacobianEvaluations();
  if (counters != nullptr) *counters = solver.counters();
  return result;
}

}  // namespace hindsight
