// The scenarios of one optimization (problems/rod/scenarios.h) evaluated across the processes and
// threads of a run.
//
// Distribution: scenario s belongs to rank s mod N (static, known to every rank; rank 0 always has
// scenario 0). Each rank evaluates its own scenarios -- in parallel threads when it has several
// (problems/rod/parallel.h) -- each with its own PistonRod and its own trajectory storage. Then every
// rank receives every scenario's results (one MPI_Allgatherv, problems/topopt/communicator.h) and
// unpacks them into scenario order. Every later combination (weighted sums, maxima, the MMA update)
// runs on every rank over the scenarios in index order, so each rank holds the same bits, and those
// are the bits of a run with one rank and one thread: a scenario's numbers do not depend on where it
// was computed, and the order of every sum is fixed by the scenario index alone.
//
// Failures are collective: every rank learns every scenario's status. A NumericalError in any
// scenario becomes a NumericalError on every rank (so the optimizer's backtracking takes the same
// decision everywhere); any other failure becomes std::runtime_error on every rank, naming the
// scenario; the owning rank's message carries the original text. No rank is left waiting.
#pragma once

#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/topopt/communicator.h>

#include <optional>
#include <string>
#include <vector>

namespace hindsight {

/// Every scenario's results at one design, identical on every rank.
struct ScenarioResults {
  std::vector<double> psi1;      ///< per scenario
  std::vector<double> psi2;      ///< per scenario (NaN when not requested)
  std::vector<Vector> gradient;  ///< per scenario: d psi_s / dx of the requested objective (or empty)
  double volumeFraction = 0.0;   ///< the design's (the same in every scenario)
  Vector dvolume;
  double localSeconds = 0.0;     ///< this rank's evaluation of its own scenarios (wall)
  double exchangeSeconds = 0.0;  ///< in the exchange, waiting for the slowest rank included (wall)
  /// This rank's full evaluation of the first scenario it owns (modes, frequencies); rank 0: scenario 0.
  std::optional<PistonRodEvaluation> local;
};

class ScenarioObjective {
 public:
  /// One PistonRod per scenario (scenarioConfigs); throws std::invalid_argument naming the field.
  ScenarioObjective(const Config& config, const Communicator& communicator);

  int count() const { return static_cast<int>(rods_.size()); }
  const std::string& name(int s) const { return cases_[static_cast<std::size_t>(s)].name; }
  double weight(int s) const { return cases_[static_cast<std::size_t>(s)].weight; }
  const PistonRod& rod(int s) const { return rods_[static_cast<std::size_t>(s)]; }
  bool owns(int s) const { return s % communicator_.size() == communicator_.rank(); }
  const Communicator& communicator() const { return communicator_; }

  /// Evaluates every scenario at `design` (collective: every rank calls it with the same design).
  /// `psi1Objective` selects which gradient is gathered (dpsi1 or dpsi2, when requested).
  ScenarioResults evaluate(ConstVectorRef design, const PistonRod::Request& request,
                           bool psi1Objective) const;

 private:
  std::vector<ScenarioCase> cases_;
  std::vector<PistonRod> rods_;
  const Communicator& communicator_;
  bool named_;  // the configuration lists scenarios (errors name them); false: the plain rod
};

}  // namespace hindsight
