/* A 2-D reaction-diffusion system (Gray-Scott kinetics) on a periodic DMDA, with PETSc TSAdjoint: a
   plain PETSc program that knows nothing of hindsight (the trajectory type comes from the options).

     u_t = D1 (u_xx + u_yy) - u v^2 + gamma (1 - u)
     v_t = D2 (v_xx + v_yy) + u v^2 - (gamma + kappa) v        on [0, L]^2, periodic

   J = u(T) at the centre grid point; lambda(0) = dJ/d(u, v)(0) everywhere.
   Options: -out FILE  writes lambda(0) with VecView in PETSc binary (natural ordering, so the file
                       does not depend on the number of ranks);
            -fd        prints adjoint and central-difference values of dJ/du(0), dJ/dv(0) at the centre
                       and dJ/du(0) at a neighbour (forward solves without trajectory; -fd_eps E). */
#include <petscdm.h>
#include <petscdmda.h>
#include <petscts.h>

typedef struct {
  PetscScalar u, v;
} Field;

typedef struct {
  DM        da;
  PetscReal D1, D2, gamma, kappa, L;
} AppCtx;

static PetscErrorCode rhs(TS ts, PetscReal t, Vec U, Vec F, void *ptr) {
  AppCtx   *app = (AppCtx *)ptr;
  DM        da  = app->da;
  Vec       local;
  Field   **u, **f;
  PetscInt  i, j, xs, ys, xm, ym, M, N;
  PetscReal hx, hy, sx, sy;
  (void)ts;
  (void)t;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(da, NULL, &M, &N, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  hx = app->L / M;
  hy = app->L / N;
  sx = 1.0 / (hx * hx);
  sy = 1.0 / (hy * hy);
  PetscCall(DMGetLocalVector(da, &local));
  PetscCall(DMGlobalToLocalBegin(da, U, INSERT_VALUES, local));
  PetscCall(DMGlobalToLocalEnd(da, U, INSERT_VALUES, local));
  PetscCall(DMDAVecGetArrayRead(da, local, &u));
  PetscCall(DMDAVecGetArray(da, F, &f));
  PetscCall(DMDAGetCorners(da, &xs, &ys, NULL, &xm, &ym, NULL));
  for (j = ys; j < ys + ym; j++) {
    for (i = xs; i < xs + xm; i++) {
      const PetscScalar uc = u[j][i].u, vc = u[j][i].v, uvv = uc * vc * vc;
      const PetscScalar uxx = (u[j][i - 1].u - 2.0 * uc + u[j][i + 1].u) * sx;
      const PetscScalar uyy = (u[j - 1][i].u - 2.0 * uc + u[j + 1][i].u) * sy;
      const PetscScalar vxx = (u[j][i - 1].v - 2.0 * vc + u[j][i + 1].v) * sx;
      const PetscScalar vyy = (u[j - 1][i].v - 2.0 * vc + u[j + 1][i].v) * sy;
      f[j][i].u = app->D1 * (uxx + uyy) - uvv + app->gamma * (1.0 - uc);
      f[j][i].v = app->D2 * (vxx + vyy) + uvv - (app->gamma + app->kappa) * vc;
    }
  }
  PetscCall(DMDAVecRestoreArrayRead(da, local, &u));
  PetscCall(DMDAVecRestoreArray(da, F, &f));
  PetscCall(DMRestoreLocalVector(da, &local));
  PetscCall(PetscLogFlops(20.0 * xm * ym));
  PetscFunctionReturn(0);
}

static PetscErrorCode rhsJacobian(TS ts, PetscReal t, Vec U, Mat A, Mat B, void *ptr) {
  AppCtx     *app = (AppCtx *)ptr;
  DM          da  = app->da;
  Vec         local;
  Field     **u;
  PetscInt    i, j, xs, ys, xm, ym, M, N;
  PetscReal   hx, hy, sx, sy;
  MatStencil  row, col[6];
  PetscScalar val[6];
  (void)ts;
  (void)t;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(da, NULL, &M, &N, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  hx = app->L / M;
  hy = app->L / N;
  sx = 1.0 / (hx * hx);
  sy = 1.0 / (hy * hy);
  PetscCall(DMGetLocalVector(da, &local));
  PetscCall(DMGlobalToLocalBegin(da, U, INSERT_VALUES, local));
  PetscCall(DMGlobalToLocalEnd(da, U, INSERT_VALUES, local));
  PetscCall(DMDAVecGetArrayRead(da, local, &u));
  PetscCall(DMDAGetCorners(da, &xs, &ys, NULL, &xm, &ym, NULL));
  for (j = ys; j < ys + ym; j++) {
    for (i = xs; i < xs + xm; i++) {
      const PetscScalar uc = u[j][i].u, vc = u[j][i].v;
      for (PetscInt c = 0; c < 2; ++c) {
        const PetscReal D = c == 0 ? app->D1 : app->D2;
        row.i = i;
        row.j = j;
        row.c = c;
        col[0].i = i - 1; col[0].j = j;     col[0].c = c; val[0] = D * sx;
        col[1].i = i + 1; col[1].j = j;     col[1].c = c; val[1] = D * sx;
        col[2].i = i;     col[2].j = j - 1; col[2].c = c; val[2] = D * sy;
        col[3].i = i;     col[3].j = j + 1; col[3].c = c; val[3] = D * sy;
        col[4].i = i;     col[4].j = j;     col[4].c = 0;
        col[5].i = i;     col[5].j = j;     col[5].c = 1;
        if (c == 0) {
          val[4] = -2.0 * D * (sx + sy) - vc * vc - app->gamma;
          val[5] = -2.0 * uc * vc;
        } else {
          val[4] = vc * vc;
          val[5] = -2.0 * D * (sx + sy) + 2.0 * uc * vc - (app->gamma + app->kappa);
        }
        PetscCall(MatSetValuesStencil(B, 1, &row, 6, col, val, INSERT_VALUES));
      }
    }
  }
  PetscCall(DMDAVecRestoreArrayRead(da, local, &u));
  PetscCall(DMRestoreLocalVector(da, &local));
  PetscCall(MatAssemblyBegin(B, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(B, MAT_FINAL_ASSEMBLY));
  if (A != B) {
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  }
  PetscFunctionReturn(0);
}

/* A smooth bump in the middle of the square; `delta` is added to component c at grid point (pi, pj). */
static PetscErrorCode initialState(AppCtx *app, Vec U, PetscInt pi, PetscInt pj, PetscInt pc, PetscReal delta) {
  DM       da = app->da;
  Field  **u;
  PetscInt i, j, xs, ys, xm, ym, M, N;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(da, NULL, &M, &N, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  PetscCall(DMDAVecGetArray(da, U, &u));
  PetscCall(DMDAGetCorners(da, &xs, &ys, NULL, &xm, &ym, NULL));
  for (j = ys; j < ys + ym; j++) {
    for (i = xs; i < xs + xm; i++) {
      const PetscReal x = app->L * i / M, y = app->L * j / N;
      const PetscReal sx = PetscSinReal(PETSC_PI * x / app->L), sy = PetscSinReal(PETSC_PI * y / app->L);
      const PetscReal s = PetscPowReal(sx * sy, 8.0);
      u[j][i].u = 1.0 - 0.5 * s;
      u[j][i].v = 0.25 * s;
      if (i == pi && j == pj) {
        if (pc == 0) u[j][i].u += delta;
        else u[j][i].v += delta;
      }
    }
  }
  PetscCall(DMDAVecRestoreArray(da, U, &u));
  PetscFunctionReturn(0);
}

/* Component c of U at grid point (pi, pj), on every rank. */
static PetscErrorCode valueAt(AppCtx *app, Vec U, PetscInt pi, PetscInt pj, PetscInt pc, PetscReal *value) {
  Field   **u;
  PetscInt  xs, ys, xm, ym;
  PetscReal mine = 0.0;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetCorners(app->da, &xs, &ys, NULL, &xm, &ym, NULL));
  PetscCall(DMDAVecGetArrayRead(app->da, U, &u));
  if (pi >= xs && pi < xs + xm && pj >= ys && pj < ys + ym) mine = pc == 0 ? u[pj][pi].u : u[pj][pi].v;
  PetscCall(DMDAVecRestoreArrayRead(app->da, U, &u));
  PetscCallMPI(MPI_Allreduce(&mine, value, 1, MPIU_REAL, MPIU_SUM, PETSC_COMM_WORLD));
  PetscFunctionReturn(0);
}

static PetscErrorCode createTS(AppCtx *app, Mat J, PetscBool save, TS *ts) {
  PetscFunctionBeginUser;
  PetscCall(TSCreate(PETSC_COMM_WORLD, ts));
  PetscCall(TSSetDM(*ts, app->da));
  PetscCall(TSSetProblemType(*ts, TS_NONLINEAR));
  PetscCall(TSSetType(*ts, TSRK));
  PetscCall(TSSetRHSFunction(*ts, NULL, rhs, app));
  if (J) PetscCall(TSSetRHSJacobian(*ts, J, J, rhsJacobian, app));
  PetscCall(TSSetMaxTime(*ts, 1e6));
  PetscCall(TSSetMaxSteps(*ts, 50));
  PetscCall(TSSetTimeStep(*ts, 0.5));
  PetscCall(TSSetExactFinalTime(*ts, TS_EXACTFINALTIME_MATCHSTEP));
  if (save) PetscCall(TSSetSaveTrajectory(*ts));
  PetscCall(TSSetFromOptions(*ts));
  PetscFunctionReturn(0);
}

static PetscErrorCode objective(AppCtx *app, Mat J, PetscInt pi, PetscInt pj, PetscInt pc, PetscReal delta, PetscReal *value) {
  TS  ts;
  Vec U;
  PetscInt M;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(app->da, NULL, &M, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  PetscCall(DMCreateGlobalVector(app->da, &U));
  PetscCall(initialState(app, U, pi, pj, pc, delta));
  PetscCall(createTS(app, J, PETSC_FALSE, &ts));
  PetscCall(TSSolve(ts, U));
  PetscCall(valueAt(app, U, M / 2, M / 2, 0, value));
  PetscCall(TSDestroy(&ts));
  PetscCall(VecDestroy(&U));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  AppCtx      app;
  TS          ts;
  Vec         U, lambda[1];
  Mat         J;
  PetscInt    M = 32;
  PetscBool   fd = PETSC_FALSE, haveOut = PETSC_FALSE;
  PetscReal   eps = 1e-6;
  char        out[PETSC_MAX_PATH_LEN];
  PetscInt    c;

  PetscFunctionBeginUser;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-grid", &M, NULL));
  PetscCall(PetscOptionsGetBool(NULL, NULL, "-fd", &fd, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-fd_eps", &eps, NULL));
  PetscCall(PetscOptionsGetString(NULL, NULL, "-out", out, sizeof(out), &haveOut));
  app.D1    = 8.0e-5;
  app.D2    = 4.0e-5;
  app.gamma = 0.024;
  app.kappa = 0.06;
  app.L     = 2.5;
  PetscCall(DMDACreate2d(PETSC_COMM_WORLD, DM_BOUNDARY_PERIODIC, DM_BOUNDARY_PERIODIC, DMDA_STENCIL_STAR, M, M, PETSC_DECIDE, PETSC_DECIDE, 2, 1, NULL, NULL, &app.da));
  PetscCall(DMSetFromOptions(app.da));
  PetscCall(DMSetUp(app.da));
  PetscCall(DMCreateMatrix(app.da, &J));
  PetscCall(DMCreateGlobalVector(app.da, &U));
  PetscCall(initialState(&app, U, -1, -1, 0, 0.0));

  PetscCall(createTS(&app, J, PETSC_TRUE, &ts));
  PetscCall(TSSolve(ts, U));

  PetscCall(DMCreateGlobalVector(app.da, &lambda[0]));
  PetscCall(VecSet(lambda[0], 0.0));
  {
    Field  **l;
    PetscInt xs, ys, xm, ym;
    PetscCall(DMDAGetCorners(app.da, &xs, &ys, NULL, &xm, &ym, NULL));
    PetscCall(DMDAVecGetArray(app.da, lambda[0], &l));
    if (M / 2 >= xs && M / 2 < xs + xm && M / 2 >= ys && M / 2 < ys + ym) l[M / 2][M / 2].u = 1.0;
    PetscCall(DMDAVecRestoreArray(app.da, lambda[0], &l));
  }
  PetscCall(TSSetCostGradients(ts, 1, lambda, NULL));
  PetscCall(TSAdjointSolve(ts));

  {
    PetscReal norm;
    PetscCall(VecNorm(lambda[0], NORM_2, &norm));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "adjoint |lambda(0)| %.17g\n", (double)norm));
  }
  if (haveOut) {
    PetscViewer viewer;
    PetscCall(PetscViewerBinaryOpen(PETSC_COMM_WORLD, out, FILE_MODE_WRITE, &viewer));
    PetscCall(PetscViewerBinarySetSkipInfo(viewer, PETSC_TRUE));
    PetscCall(VecView(lambda[0], viewer));
    PetscCall(PetscViewerDestroy(&viewer));
  }
  if (fd) {
    const PetscInt points[3][3] = {
      {M / 2,     M / 2, 0},
      {M / 2,     M / 2, 1},
      {M / 2 + 1, M / 2, 0}
    };
    for (c = 0; c < 3; ++c) {
      PetscReal plus, minus, adjoint;
      PetscCall(objective(&app, J, points[c][0], points[c][1], points[c][2], eps, &plus));
      PetscCall(objective(&app, J, points[c][0], points[c][1], points[c][2], -eps, &minus));
      PetscCall(valueAt(&app, lambda[0], points[c][0], points[c][1], points[c][2], &adjoint));
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "check point %d adjoint %.17g fd %.17g\n", (int)c, (double)adjoint, (double)((plus - minus) / (2 * eps))));
    }
  }

  PetscCall(VecDestroy(&lambda[0]));
  PetscCall(VecDestroy(&U));
  PetscCall(MatDestroy(&J));
  PetscCall(TSDestroy(&ts));
  PetscCall(DMDestroy(&app.da));
  PetscCall(PetscFinalize());
  return 0;
}
