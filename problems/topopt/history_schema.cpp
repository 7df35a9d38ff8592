#include <hindsight/problems/topopt/history_schema.h>

#include <nlohmann/json.hpp>

#include <limits>
#include <sstream>

namespace hindsight {
namespace {

constexpr double kLargest = std::numeric_limits<double>::max();
constexpr double kSmallestPositive = std::numeric_limits<double>::min();

HistoryColumn integerColumn(const char* name, const char* description, HistoryRule rule, double upper,
                            int IterationRecord::*member, bool optional = false) {
  return {name, HistoryColumnType::int32, "1", description, true,    optional,
          rule, HistoryNaN::never,        0.0, upper,       nullptr, member};
}

HistoryColumn realColumn(const char* name, const char* unit, const char* description, bool reproducible,
                         HistoryNaN nan, double lower, double upper, double IterationRecord::*member,
                         bool optional = false) {
  return {name,
          HistoryColumnType::float64,
          unit,
          description,
          reproducible,
          optional,
          HistoryRule::range,
          nan,
          lower,
          upper,
          member,
          nullptr};
}

std::vector<HistoryColumn> makeColumns() {
  // The file order of format 2 (results_file.h): the root hash depends on it.
  return {
      integerColumn("iteration", "Index of the row: the number of design updates before this evaluation.",
                    HistoryRule::rowIndex, kLargest, &IterationRecord::iteration),
      integerColumn("backtracks",
                    "Halvings toward the previous design after a diverged simulation in this iteration.",
                    HistoryRule::range, TopologyOptimizer::maxBacktracks, &IterationRecord::backtracks),
      realColumn("psi1", "J s", "Integral compliance of the design (with scenarios: of the worst scenario).",
                 true, HistoryNaN::never, kSmallestPositive, kLargest, &IterationRecord::psi1),
      realColumn("psi2", "J s", "Equivalent-static-load compliance (with scenarios: of the worst scenario).",
                 true, HistoryNaN::never, kSmallestPositive, kLargest, &IterationRecord::psi2),
      realColumn("volume_fraction", "1", "V/V0 over all elements, the solid end columns included.", true,
                 HistoryNaN::never, kSmallestPositive, 1.0, &IterationRecord::volumeFraction),
      realColumn("max_design_change", "1",
                 "Largest change of a design variable made by this iteration's update (NaN for the final "
                 "evaluation).",
                 true, HistoryNaN::finalEvaluation, 0.0, kLargest, &IterationRecord::maxDesignChange),
      realColumn("evaluation_seconds", "s", "Wall time of the simulation and its gradients.", false,
                 HistoryNaN::never, 0.0, kLargest, &IterationRecord::evaluationSeconds),
      realColumn("mma_seconds", "s", "Wall time of the optimizer's update.", false, HistoryNaN::never, 0.0,
                 kLargest, &IterationRecord::mmaSeconds),
      realColumn("total_seconds", "s", "Wall time of the iteration (evaluation, update, pictures).", false,
                 HistoryNaN::never, 0.0, kLargest, &IterationRecord::totalSeconds),
      realColumn("grayness", "1", "Fraction of the design elements whose density lies in (0.1, 0.9).", true,
                 HistoryNaN::allowed, 0.0, 1.0, &IterationRecord::grayness, true),
      realColumn("first_frequency_hz", "Hz", "First natural frequency of the pinned-roller rod.", true,
                 HistoryNaN::allowed, 0.0, kLargest, &IterationRecord::firstFrequencyHz, true),
      realColumn("kkt_residual", "1",
                 "First-order optimality residual with the update's multipliers (NaN where no update was "
                 "computed; a finished run whose last row has one stopped by the convergence rule).",
                 true, HistoryNaN::allowed, 0.0, kLargest, &IterationRecord::kktResidual, true),
      integerColumn(
          "inner_iterations", "GCMMA: trial designs simulated in this iteration's update (0 for MMA).",
          HistoryRule::range, std::numeric_limits<int>::max(), &IterationRecord::innerIterations, true),
  };
}

const char* typeName(HistoryColumnType type) {
  return type == HistoryColumnType::int32 ? "int32" : "float64";
}

}  // namespace

const std::vector<HistoryColumn>& historyColumns() {
  static const std::vector<HistoryColumn> columns = makeColumns();
  return columns;
}

double historyValue(const HistoryColumn& column, const IterationRecord& record) {
  return column.real != nullptr ? record.*(column.real) : static_cast<double>(record.*(column.integer));
}

std::string historyColumnsJson() {
  nlohmann::ordered_json columns = nlohmann::ordered_json::array();
  for (const HistoryColumn& c : historyColumns()) {
    columns.push_back({{"name", c.name},
                       {"type", typeName(c.type)},
                       {"unit", c.unit},
                       {"description", c.description},
                       {"reproducible", c.reproducible},
                       {"optional", c.optional}});
  }
  nlohmann::ordered_json document;
  document["columns"] = columns;
  return document.dump(2) + "\n";
}

std::string historyColumnsMarkdown() {
  std::ostringstream out;
  out << "| column | type | unit | description |\n|---|---|---|---|\n";
  for (const HistoryColumn& c : historyColumns()) {
    out << "| `" << c.name << "` | " << typeName(c.type) << " | " << c.unit << " | " << c.description
        << (c.optional ? " Absent from files written before it existed." : "") << " |\n";
  }
  return out.str();
}

}  // namespace hindsight
