#include <hindsight/problems/topopt/scenario_objective.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/problems/rod/parallel.h>

#include <exception>
#include <stdexcept>
#include <typeinfo>

namespace hindsight {
namespace {

// A scenario's outcome, exchanged between ranks so that every rank throws the same kind of failure:
// a numerical one (the optimizer's divergence guard and GCMMA step back from it), a storage failure
// and bad input (exit codes 3 and 2), or anything else.
enum Status { kOk = 0, kNumerical = 1, kFailed = 2, kStorage = 3, kInput = 4 };

std::vector<PistonRod> makeRods(const Config& config) {
  // The scenarios share the mesh: one pool keeps K's factorisation for all of them, one per scenario
  // evaluated at the same time (not one per scenario: 300 MB each at 1600 x 96).
  const auto factorizations = std::make_shared<rod::StiffnessFactorizationPool>();
  std::vector<PistonRod> rods;
  for (const Config& c : scenarioConfigs(config)) rods.emplace_back(c, factorizations);
  return rods;
}

}  // namespace

ScenarioObjective::ScenarioObjective(const Config& config, const Communicator& communicator)
    : cases_(scenarioCases(config)),
      rods_(makeRods(config)),
      communicator_(communicator),
      named_(!config.scenarios.empty()) {}

ScenarioResults ScenarioObjective::evaluate(ConstVectorRef design, const PistonRod::Request& request,
                                            bool psi1Objective) const {
  const int total = count();
  const Eigen::Index n = design.size();
  std::vector<int> mine;
  for (int s = 0; s < total; ++s) {
    if (owns(s)) mine.push_back(s);
  }
  // This rank's scenarios, in parallel threads; every outcome (value or exception) kept in its slot.
  std::vector<std::optional<PistonRodEvaluation>> evaluations(mine.size());
  std::vector<std::exception_ptr> errors(mine.size());
  std::vector<int> status(mine.size(), kOk);
  std::vector<double> times(mine.size(), 0.0);  // of a NumericalError
  Stopwatch timer;
  parallelFor(static_cast<int>(mine.size()), [&](int k) {
    const auto slot = static_cast<std::size_t>(k);
    try {
      evaluations[slot] = rods_[static_cast<std::size_t>(mine[slot])].evaluate(design, request);
    } catch (const NumericalError& e) {
      errors[slot] = std::current_exception();
      status[slot] = kNumerical;
      times[slot] = e.time();
    } catch (const StorageError&) {
      errors[slot] = std::current_exception();
      status[slot] = kStorage;
    } catch (const std::invalid_argument&) {
      errors[slot] = std::current_exception();
      status[slot] = kInput;
    } catch (...) {
      errors[slot] = std::current_exception();
      status[slot] = kFailed;
    }
  });

  // One process running the plain rod: the exception as it was, so that messages and exit codes are
  // those of a run without scenarios.
  if (!named_ && !communicator_.parallel() && errors[0]) std::rethrow_exception(errors[0]);

  // Packet per owned scenario: status, psi1, psi2, volume fraction, gradient (n), dvolume (n).
  const std::size_t packet = 4 + 2 * static_cast<std::size_t>(n);
  std::vector<double> send(mine.size() * packet, 0.0);
  const bool gradient = psi1Objective ? request.psi1Gradient : request.psi2Gradient;
  for (std::size_t k = 0; k < mine.size(); ++k) {
    double* p = send.data() + k * packet;
    p[0] = status[k];
    p[1] = times[k];
    if (status[k] != kOk) continue;
    const PistonRodEvaluation& e = *evaluations[k];
    p[1] = e.psi1;
    p[2] = e.psi2;
    p[3] = e.volumeFraction;
    const Vector& g = psi1Objective ? e.dpsi1 : e.dpsi2;
    if (gradient) std::copy(g.data(), g.data() + n, p + 4);
    std::copy(e.dvolume.data(), e.dvolume.data() + n, p + 4 + n);
  }
  const double localSeconds = timer.restart();
  const std::vector<double> all = communicator_.allGather(send);
  const double exchangeSeconds = timer.seconds();

  // Rank r's packets come in its scenario order r, r + N, r + 2N, ...
  const int ranks = communicator_.size();
  std::vector<const double*> packets(static_cast<std::size_t>(total));
  std::size_t offset = 0;
  for (int r = 0; r < ranks; ++r) {
    for (int s = r; s < total; s += ranks) {
      packets[static_cast<std::size_t>(s)] = all.data() + offset;
      offset += packet;
    }
  }
  for (int s = 0; s < total; ++s) {  // the first failure in scenario order decides, on every rank
    const int code = static_cast<int>(packets[static_cast<std::size_t>(s)][0]);
    if (code == kOk) continue;
    const std::string who = "scenario '" + name(s) + "'";
    std::string text = "failed on rank " + std::to_string(s % ranks) + " (that rank reports the error)";
    std::string path;
    for (std::size_t k = 0; k < mine.size(); ++k) {
      if (mine[k] != s) continue;
      try {
        std::rethrow_exception(errors[k]);
      } catch (const NumericalError& e) {
        text = e.what();
        text = text.substr(0, text.rfind(" (at t = "));  // NumericalError adds it again below
      } catch (const StorageError& e) {
        text = e.what();
        if (!e.path().empty()) text = text.substr(0, text.rfind(" [file: "));  // StorageError adds it again
        path = e.path();
      } catch (const std::invalid_argument& e) {
        text = e.what();
      } catch (const std::exception& e) {
        // A plain library failure gets the scenario's name; an exception of any other type -- an
        // interrupt (Python's KeyboardInterrupt travels as pybind11's error_already_set) -- keeps its
        // type: rewrapping it would turn Ctrl-C into a "failure".
        if (typeid(e) != typeid(std::runtime_error) && typeid(e) != typeid(std::logic_error)) throw;
        text = e.what();
      } catch (...) {
        throw;
      }
    }
    if (code == kNumerical) throw NumericalError(who + ": " + text, packets[static_cast<std::size_t>(s)][1]);
    if (code == kStorage) throw StorageError(who + ": " + text, path);
    if (code == kInput) throw std::invalid_argument(who + ": " + text);
    throw std::runtime_error(who + ": " + text);
  }

  ScenarioResults out;
  out.localSeconds = localSeconds;
  out.exchangeSeconds = exchangeSeconds;
  for (int s = 0; s < total; ++s) {
    const double* p = packets[static_cast<std::size_t>(s)];
    out.psi1.push_back(p[1]);
    out.psi2.push_back(p[2]);
    out.gradient.push_back(gradient ? Vector(Eigen::Map<const Vector>(p + 4, n)) : Vector());
    if (s == 0) {
      out.volumeFraction = p[3];
      out.dvolume = Eigen::Map<const Vector>(p + 4 + n, n);
    }
  }
  if (!mine.empty()) out.local = std::move(evaluations[0]);
  return out;
}

}  // namespace hindsight
