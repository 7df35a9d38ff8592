/* Van der Pol oscillator with PETSc TSAdjoint: a plain PETSc program that knows nothing of hindsight
   (the trajectory type comes from the options, -dll_append ... -ts_trajectory_type hindsight).

     x0' = x1,   x1' = mu ((1 - x0^2) x1 - x0),   J = x0(T)

   Prints dJ/dx(0) and dJ/dmu from TSAdjointSolve as C99 hex floats (every bit), and with -fd the same
   derivatives from central differences of fresh forward solves (no trajectory).
   Options: -mu M (default 1.5), -x0 A,B (default 2,0), -fd, -fd_eps E (default 1e-6). */
#include <petscts.h>

typedef struct {
  PetscReal mu;
} Ctx;

static PetscErrorCode rhs(TS ts, PetscReal t, Vec X, Vec F, void *ptr) {
  Ctx               *ctx = (Ctx *)ptr;
  const PetscScalar *x;
  PetscScalar       *f;
  (void)ts;
  (void)t;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(X, &x));
  PetscCall(VecGetArray(F, &f));
  f[0] = x[1];
  f[1] = ctx->mu * ((1.0 - x[0] * x[0]) * x[1] - x[0]);
  PetscCall(VecRestoreArrayRead(X, &x));
  PetscCall(VecRestoreArray(F, &f));
  PetscFunctionReturn(0);
}

static PetscErrorCode rhsJacobian(TS ts, PetscReal t, Vec X, Mat A, Mat B, void *ptr) {
  Ctx               *ctx = (Ctx *)ptr;
  const PetscScalar *x;
  PetscInt           rows[2] = {0, 1};
  PetscScalar        J[4];
  (void)ts;
  (void)t;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(X, &x));
  J[0] = 0.0;
  J[1] = 1.0;
  J[2] = ctx->mu * (-2.0 * x[0] * x[1] - 1.0);
  J[3] = ctx->mu * (1.0 - x[0] * x[0]);
  PetscCall(MatSetValues(B, 2, rows, 2, rows, J, INSERT_VALUES));
  PetscCall(VecRestoreArrayRead(X, &x));
  PetscCall(MatAssemblyBegin(B, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(B, MAT_FINAL_ASSEMBLY));
  if (A != B) {
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode rhsJacobianP(TS ts, PetscReal t, Vec X, Mat A, void *ptr) {
  const PetscScalar *x;
  PetscInt           rows[2] = {0, 1}, col = 0;
  PetscScalar        J[2];
  (void)ts;
  (void)t;
  (void)ptr;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(X, &x));
  J[0] = 0.0;
  J[1] = (1.0 - x[0] * x[0]) * x[1] - x[0];
  PetscCall(MatSetValues(A, 2, rows, 1, &col, J, INSERT_VALUES));
  PetscCall(VecRestoreArrayRead(X, &x));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

/* J = x0(T) from a forward solve (the options' TS, no trajectory). */
static PetscErrorCode forward(PetscReal mu, const PetscReal x0[2], PetscReal *J) {
  TS           ts;
  Vec          X;
  Ctx          ctx = {mu};
  PetscScalar *x;
  PetscFunctionBeginUser;
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, 2, &X));
  PetscCall(VecGetArray(X, &x));
  x[0] = x0[0];
  x[1] = x0[1];
  PetscCall(VecRestoreArray(X, &x));
  PetscCall(TSCreate(PETSC_COMM_SELF, &ts));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSSetRHSFunction(ts, NULL, rhs, &ctx));
  PetscCall(TSSetMaxTime(ts, 2.0));
  PetscCall(TSSetTimeStep(ts, 0.01));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  PetscCall(TSSetFromOptions(ts));
  PetscCall(TSSolve(ts, X));
  PetscCall(VecGetArray(X, &x));
  *J = x[0];
  PetscCall(VecRestoreArray(X, &x));
  PetscCall(TSDestroy(&ts));
  PetscCall(VecDestroy(&X));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  TS           ts;
  Vec          X, lambda[1], mup[1];
  Mat          A, Jp;
  Ctx          ctx;
  PetscReal    x0[2] = {2.0, 0.0}, eps = 1e-6;
  PetscInt     n    = 2;
  PetscBool    fd   = PETSC_FALSE;
  PetscScalar *x;
  PetscMPIInt  size;

  PetscFunctionBeginUser;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
  PetscCheck(size == 1, PETSC_COMM_WORLD, PETSC_ERR_WRONG_MPI_SIZE, "a two-state ODE runs on one rank");
  ctx.mu = 1.5;
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-mu", &ctx.mu, NULL));
  PetscCall(PetscOptionsGetRealArray(NULL, NULL, "-x0", x0, &n, NULL));
  PetscCall(PetscOptionsGetBool(NULL, NULL, "-fd", &fd, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-fd_eps", &eps, NULL));

  PetscCall(MatCreateDense(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, 2, 2, NULL, &A));
  PetscCall(MatSetUp(A));
  PetscCall(MatCreateDense(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, 2, 1, NULL, &Jp));
  PetscCall(MatSetUp(Jp));
  PetscCall(MatCreateVecs(A, &X, NULL));
  PetscCall(VecGetArray(X, &x));
  x[0] = x0[0];
  x[1] = x0[1];
  PetscCall(VecRestoreArray(X, &x));

  PetscCall(TSCreate(PETSC_COMM_WORLD, &ts));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSSetRHSFunction(ts, NULL, rhs, &ctx));
  PetscCall(TSSetRHSJacobian(ts, A, A, rhsJacobian, &ctx));
  PetscCall(TSSetRHSJacobianP(ts, Jp, rhsJacobianP, &ctx));
  PetscCall(TSSetMaxTime(ts, 2.0));
  PetscCall(TSSetTimeStep(ts, 0.01));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  PetscCall(TSSetSaveTrajectory(ts));
  PetscCall(TSSetFromOptions(ts));
  PetscCall(TSSolve(ts, X));

  PetscCall(MatCreateVecs(A, &lambda[0], NULL));
  PetscCall(MatCreateVecs(Jp, &mup[0], NULL));
  PetscCall(VecSet(lambda[0], 0.0));
  PetscCall(VecSetValue(lambda[0], 0, 1.0, INSERT_VALUES));
  PetscCall(VecAssemblyBegin(lambda[0]));
  PetscCall(VecAssemblyEnd(lambda[0]));
  PetscCall(VecSet(mup[0], 0.0));
  PetscCall(TSSetCostGradients(ts, 1, lambda, mup));
  PetscCall(TSAdjointSolve(ts));

  {
    const PetscScalar *l, *m;
    PetscInt           steps;
    PetscCall(TSGetStepNumber(ts, &steps));
    PetscCall(VecGetArrayRead(lambda[0], &l));
    PetscCall(VecGetArrayRead(mup[0], &m));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "adjoint dJ/dx0 %a %a dJ/dmu %a\n", (double)l[0], (double)l[1], (double)m[0]));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "adjoint-decimal dJ/dx0 %.17g %.17g dJ/dmu %.17g\n", (double)l[0], (double)l[1], (double)m[0]));
    PetscCall(VecRestoreArrayRead(lambda[0], &l));
    PetscCall(VecRestoreArrayRead(mup[0], &m));
  }
  if (fd) {
    PetscReal plus, minus, g[3], p[2];
    for (PetscInt i = 0; i < 2; ++i) {
      p[0] = x0[0];
      p[1] = x0[1];
      p[i] += eps;
      PetscCall(forward(ctx.mu, p, &plus));
      p[i] -= 2 * eps;
      PetscCall(forward(ctx.mu, p, &minus));
      g[i] = (plus - minus) / (2 * eps);
    }
    PetscCall(forward(ctx.mu + eps, x0, &plus));
    PetscCall(forward(ctx.mu - eps, x0, &minus));
    g[2] = (plus - minus) / (2 * eps);
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "fd-decimal dJ/dx0 %.17g %.17g dJ/dmu %.17g\n", (double)g[0], (double)g[1], (double)g[2]));
  }

  PetscCall(VecDestroy(&lambda[0]));
  PetscCall(VecDestroy(&mup[0]));
  PetscCall(VecDestroy(&X));
  PetscCall(MatDestroy(&A));
  PetscCall(MatDestroy(&Jp));
  PetscCall(TSDestroy(&ts));
  PetscCall(PetscFinalize());
  return 0;
}
