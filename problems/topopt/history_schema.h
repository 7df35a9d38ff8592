// The columns of an optimization's history: one table from which everything that names them is driven.
//
// Each row of the table below is one column: the dataset /history/<name> in results.h5
// (problems/topopt/results_file.h writes, reads and checks it from this table alone), the key of
// hindsight.read_results()'s history and of hindsight.optimize()'s callback records
// (python/module.cpp), the unit and description that `hindsight plot` labels its axes with
// (problems/topopt/plot_history.py reads problems/topopt/history_columns.json, generated from this
// table) and the table in docs/guides/results_files.md. tests/problems/topopt/history_schema_test.cpp
// checks that the JSON file and the documentation's table are exactly what historyColumnsJson() and
// historyColumnsMarkdown() produce, so a column added here and nowhere else fails a test until both are
// regenerated (HINDSIGHT_REGENERATE=1 topopt_tests --gtest_filter=HistorySchema.*).
//
// The order of the table is the order in which the columns are written, and a results file's root hash
// covers the datasets in that order (results_file.h, Integrity): new columns go at the end, marked
// `optional` (files written before them are still read, the records then keep their defaults).
#pragma once

#include <hindsight/problems/topopt/topology_optimizer.h>

#include <string>
#include <vector>

namespace hindsight {

enum class HistoryColumnType { int32, float64 };

/// Which entries of a float64 column may be NaN (an unknown value) in a plausible file.
enum class HistoryNaN {
  never,            ///< every entry finite
  finalEvaluation,  ///< all but the last row of a finished run (which made no update) finite
  allowed           ///< NaN means "not computed"; any other value must lie in [lower, upper]
};

/// What the reader checks of a column beyond its checksums.
enum class HistoryRule {
  range,    ///< every entry in [lower, upper] (see nan)
  rowIndex  ///< entry k equals k
};

struct HistoryColumn {
  const char* name;  ///< the dataset /history/NAME and the Python key
  HistoryColumnType type;
  const char* unit;         ///< SI unit, "1" for a ratio or a count
  const char* description;  ///< one sentence, as the documentation's table shows it
  /// The value is the same bits on every run of the same configuration (the seconds columns are not):
  /// the columns the reproducibility tests compare.
  bool reproducible;
  /// Absent from files written before the column existed; such files are still read.
  bool optional;
  HistoryRule rule;
  HistoryNaN nan;
  double lower;
  double upper;
  double IterationRecord::*real;  ///< the record's member (float64 columns), else nullptr
  int IterationRecord::*integer;  ///< the record's member (int32 columns), else nullptr
};

/// Every column, in file order.
const std::vector<HistoryColumn>& historyColumns();

/// The column's value in a record (an int32 column's value is exact in a double).
double historyValue(const HistoryColumn& column, const IterationRecord& record);

/// The table as JSON: {"columns": [{"name", "type", "unit", "description", "reproducible", "optional"},
/// ...]}, 2-space indented with a final newline; the content of problems/topopt/history_columns.json.
std::string historyColumnsJson();

/// The table as a Markdown table (name, type, unit, description), as docs/guides/results_files.md has it.
std::string historyColumnsMarkdown();

}  // namespace hindsight
