// The structure of the mechanism's position constraints, fixed at construction (docs/design.md §10;
// mechanism_problem.h, "The position solve"): which coordinates each equation and its Jacobian entries
// touch, the matching of equations to dependent coordinates and Tarjan's components (the
// Dulmage-Mendelsohn or BLT order), which blocks are affine or constant, and which depend on time alone.
// Kept apart from the solves (constraint_solve.cpp), which only read the index arrays built here.
#include <hindsight/problems/mechanism/detail/system.h>

#include <algorithm>
#include <cassert>
#include <functional>
#include <stdexcept>

namespace hindsight::mechanism::detail {

std::vector<std::vector<System::Entry>> System::structure() const {
  std::vector<std::vector<Entry>> eqs(m);
  auto add = [&](int e, int z, std::vector<int> coefficient) {
    for (Entry& x : eqs[e]) {
      if (x.z == z) {
        x.coefficient.insert(x.coefficient.end(), coefficient.begin(), coefficient.end());
        return;
      }
    }
    eqs[e].push_back(Entry{z, std::move(coefficient)});
  };
  // Component k of a point's position; `with` the coordinates that multiply it (a line's direction).
  auto pointTerms = [&](int e, const PointRef& r, int k, bool translation, const std::vector<int>& with) {
    if (r.body == kGround) return;
    const int o = bodyOffset(r.body);
    if (translation) add(e, o + k, with);
    std::vector<int> rotating = with;
    rotating.push_back(o + 2);
    if (r.atB || r.local != Vec2::Zero()) add(e, o + 2, rotating);
    if (r.atB) {
      for (int j = 0; j < n; ++j) add(e, base + 3 + j, rotating);
    }
  };
  for (int r = 0; r < static_cast<int>(rows.size()); ++r) {
    const Row& row = rows[r];
    const int i = rowFirst[r];
    switch (row.kind) {
      case Row::Revolute:
        for (int k = 0; k < 2; ++k) {
          pointTerms(i + k, row.p1, k, true, {});
          pointTerms(i + k, row.p2, k, true, {});
        }
        break;
      case Row::Angle:
      case Row::DriveAngle:
        if (row.body2 != kGround) add(i, bodyOffset(row.body2) + 2, {});
        if (row.body1 != kGround) add(i, bodyOffset(row.body1) + 2, {});
        break;
      case Row::Line:
      case Row::DriveLine: {
        const bool drive = row.kind == Row::DriveLine;
        // The direction u: the axis (drive) or its normal, in body1's frame.
        const double u[2] = {drive ? row.axis(0) : -row.axis(1), drive ? row.axis(1) : row.axis(0)};
        std::vector<int> direction, all;
        for (int body : {row.body1, row.body2}) {
          if (body == kGround) continue;
          for (int k = 0; k < 3; ++k) all.push_back(bodyOffset(body) + k);
        }
        if (row.body1 != kGround) direction.push_back(bodyOffset(row.body1) + 2);
        for (int k = 0; k < 2; ++k) {
          // Constant and exactly zero: the component drops out.
          const bool present = row.body1 != kGround || u[k] != 0.0;
          pointTerms(i, row.p2, k, present, direction);
          pointTerms(i, row.p1, k, present, direction);
        }
        // body1's angle turns the direction: its coefficient depends on the whole row.
        if (row.body1 != kGround) add(i, bodyOffset(row.body1) + 2, all);
        break;
      }
    }
  }
  return eqs;
}

void System::buildBlocks() {
  const std::vector<std::vector<Entry>> eqs = structure();
  std::vector<int> unknownOf(nz, -1);
  for (int j = 0; j < m; ++j) unknownOf[dependent[j]] = j;
  std::vector<std::vector<int>> adj(m);
  for (int e = 0; e < m; ++e) {
    for (const Entry& x : eqs[e]) {
      if (unknownOf[x.z] >= 0) adj[e].push_back(unknownOf[x.z]);
    }
    std::sort(adj[e].begin(), adj[e].end());
  }
  std::vector<int> eqOfUnknown(m, -1), unknownOfEq(m, -1);
  for (int e = 0; e < m; ++e) {
    std::vector<char> seen(m, 0);
    // Kuhn's augmenting path from equation e (m is at most a few hundred).
    std::function<bool(int)> augment = [&](int q) {
      for (int j : adj[q]) {
        if (seen[j]) continue;
        seen[j] = 1;
        if (eqOfUnknown[j] < 0 || augment(eqOfUnknown[j])) {
          eqOfUnknown[j] = q;
          unknownOfEq[q] = j;
          return true;
        }
      }
      return false;
    };
    if (!augment(e)) {
      throw std::invalid_argument(
          "mechanism: the constraints are structurally singular (no equation can fix some coordinate; a "
          "redundant joint or a coordinate no joint constrains)");
    }
  }
  // Tarjan: an equation's component is emitted after every component it needs.
  std::vector<int> index(m, -1), low(m, 0), stack;
  std::vector<char> onStack(m, 0);
  int counter = 0;
  Blocks& bl = blocks;
  bl = Blocks();
  std::function<void(int)> visit = [&](int e) {
    index[e] = low[e] = counter++;
    stack.push_back(e);
    onStack[e] = 1;
    for (int j : adj[e]) {
      const int q = eqOfUnknown[j];
      if (q == e) continue;
      if (index[q] < 0) {
        visit(q);
        low[e] = std::min(low[e], low[q]);
      } else if (onStack[q]) {
        low[e] = std::min(low[e], index[q]);
      }
    }
    if (low[e] != index[e]) return;
    std::vector<int> component;
    for (;;) {
      const int q = stack.back();
      stack.pop_back();
      onStack[q] = 0;
      component.push_back(q);
      if (q == e) break;
    }
    std::sort(component.begin(), component.end());
    bl.start.push_back(static_cast<int>(bl.eq.size()));
    for (int q : component) {
      bl.eq.push_back(q);
      bl.unk.push_back(unknownOfEq[q]);
    }
  };
  for (int e = 0; e < m; ++e) {
    if (index[e] < 0) visit(e);
  }
  bl.start.push_back(m);
  std::vector<int> blockOf(m);
  for (int b = 0; b < bl.count(); ++b) {
    for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) blockOf[bl.unk[p]] = b;
  }
  std::vector<int> rowOfEq(m);
  for (int r = 0; r < static_cast<int>(rows.size()); ++r) {
    for (int i = rowFirst[r]; i < (r + 1 < static_cast<int>(rows.size()) ? rowFirst[r + 1] : m); ++i)
      rowOfEq[i] = r;
  }
  for (int b = 0; b < bl.count(); ++b) {
    const int s = bl.start[b + 1] - bl.start[b];
    bl.luOffset.push_back(bl.luSize);
    bl.pivOffset.push_back(bl.pivSize);
    bl.luSize += s * s;
    bl.pivSize += s;
    bl.maxSize = std::max(bl.maxSize, s);
    std::vector<int> blockZ;
    for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) blockZ.push_back(dependent[bl.unk[p]]);
    bool affine = true, constant = true;
    bl.rowStart.push_back(static_cast<int>(bl.rowList.size()));
    for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
      const int e = bl.eq[p];
      if (std::find(bl.rowList.begin() + bl.rowStart[b], bl.rowList.end(), rowOfEq[e]) == bl.rowList.end())
        bl.rowList.push_back(rowOfEq[e]);
      bl.allStart.push_back(static_cast<int>(bl.allIndex.size()));
      bl.offStart.push_back(static_cast<int>(bl.offIndex.size()));
      for (const Entry& x : eqs[e]) {
        const int j = unknownOf[x.z];
        if (j < 0) continue;
        bl.allIndex.push_back(e + m * x.z);
        bl.allUnk.push_back(j);
        if (blockOf[j] != b) {
          assert(blockOf[j] < b);
          bl.offIndex.push_back(e + m * x.z);
          bl.offUnk.push_back(j);
        } else {
          if (!x.coefficient.empty()) constant = false;
          for (int z : x.coefficient) {
            if (std::find(blockZ.begin(), blockZ.end(), z) != blockZ.end()) affine = false;
          }
        }
      }
    }
    bl.affine.push_back(affine ? 1 : 0);
    bl.constant.push_back(constant ? 1 : 0);
  }
  bl.rowStart.push_back(static_cast<int>(bl.rowList.size()));
  bl.allStart.push_back(static_cast<int>(bl.allIndex.size()));
  bl.offStart.push_back(static_cast<int>(bl.offIndex.size()));
  for (int e = 0; e < m; ++e) {
    bl.touchStart.push_back(static_cast<int>(bl.touchList.size()));
    for (const Entry& x : eqs[e]) bl.touchList.push_back(e + m * x.z);
  }
  bl.touchStart.push_back(static_cast<int>(bl.touchList.size()));
  // Activity: a block is a function of time alone when its equations (their values and their
  // Jacobian coefficients) touch only its own unknowns and those of earlier blocks that are; the
  // block-triangular order lets one pass decide it. The independent coordinates start it.
  zActive.assign(nz, 0);
  for (int i : independent) zActive[i] = 1;
  bl.active.assign(bl.count(), 0);
  std::vector<char> eqActive(m, 0);
  for (int b = 0; b < bl.count(); ++b) {
    bool active = false;
    for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
      for (const Entry& x : eqs[bl.eq[p]]) {
        active = active || zActive[x.z];
        for (int z : x.coefficient) active = active || zActive[z];
      }
    }
    if (!active) continue;
    bl.active[b] = 1;
    for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
      zActive[dependent[bl.unk[p]]] = 1;
      eqActive[bl.eq[p]] = 1;
    }
  }
  for (int b = 0; b < bl.count(); ++b) {
    if (bl.active[b]) {
      bl.activeList.push_back(b);
    } else {
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) bl.inactiveUnknowns.push_back(bl.unk[p]);
    }
  }
  rowActive.assign(rows.size(), 0);
  for (int e = 0; e < m; ++e) {
    if (eqActive[e]) rowActive[rowOf[e]] = 1;
  }
  for (int e = 0; e < m; ++e) {
    if (rowActive[rowOf[e]]) continue;
    inactiveEquations.push_back(e);
    for (int x = bl.touchStart[e]; x < bl.touchStart[e + 1]; ++x) inactiveJacIndex.push_back(bl.touchList[x]);
  }
  // The constant blocks' factors, from the Jacobian at the initial positions (any point would do).
  bl.constantLu.assign(bl.luSize, 0.0);
  bl.constantPiv.assign(bl.pivSize, 0);
  Buffers<double> B(nz, m, f, n);
  for (int i = 0; i < nz; ++i) B.z[i] = zInitial(i);
  for (int i = 0; i < n; ++i) B.b[i] = 1.0;
  for (int b = 0; b < bl.count(); ++b) {
    if (!bl.constant[b]) continue;
    evaluateBlock(0.0, B, b, true);
    try {
      factorBlock(0.0, B.jac.data(), b, bl.constantLu.data() + bl.luOffset[b],
                  bl.constantPiv.data() + bl.pivOffset[b]);
    } catch (const NumericalError&) {
      throw std::invalid_argument(
          "mechanism: the constraints are singular (a redundant joint or a coordinate no joint "
          "constrains)");
    }
  }
}

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

std::vector<MechanismProblem::ConstraintBlock> MechanismProblem::constraintBlocks() const {
  const Impl& C = *chord_;
  std::vector<ConstraintBlock> out;
  for (int b = 0; b < C.blocks.count(); ++b) {
    ConstraintBlock block;
    for (int p = C.blocks.start[b]; p < C.blocks.start[b + 1]; ++p) {
      block.equations.push_back(C.equationNames[C.blocks.eq[p]]);
      block.unknowns.push_back(C.coordinateNames[C.dependent[C.blocks.unk[p]]]);
      block.rows.push_back(C.blocks.eq[p]);
      block.columns.push_back(C.blocks.unk[p]);
    }
    block.affine = C.blocks.affine[b] != 0;
    block.timeOnly = C.blocks.active[b] == 0;
    out.push_back(block);
  }
  return out;
}

Eigen::MatrixXi MechanismProblem::constraintPattern() const {
  const Impl& C = *chord_;
  Eigen::MatrixXi pattern = Eigen::MatrixXi::Zero(C.m, C.m);
  for (int p = 0; p < C.m; ++p) {
    for (int k = C.blocks.allStart[p]; k < C.blocks.allStart[p + 1]; ++k)
      pattern(C.blocks.eq[p], C.blocks.allUnk[k]) = 1;
  }
  return pattern;
}

}  // namespace hindsight::mechanism
