// The configuration fingerprint of a run, and its agreement by every MPI rank before the first
// evaluation (problems/topopt/communicator.h).
//
// Every rank of an MPI run reads its own command line and configuration file. Ranks that disagree
// (another --config, --set, --iterations, a scenario weight, another hindsight version) would each
// optimize a different problem while exchanging their scenarios' results, and rank 0 would write a
// results file that matches no configuration -- or hang when their iteration counts differ. So
// before anything collective, every rank hashes its effective run description -- the complete
// configuration (toJson, keys sorted: the same text for the same configuration whatever order the
// file had) and the run options that must match (output directory, resume, force, version) -- and
// the ranks compare the hashes. A mismatch throws std::invalid_argument (exit 2) on every rank
// naming each differing field and the ranks that differ from rank 0; nothing is written.
//
// The configuration's fingerprint ("fnv1a64:<16 hex digits>", FNV-1a 64 of the canonical JSON of
// the configuration alone) is stored in results.h5 with the number of ranks that agreed on it
// (problems/topopt/results_file.h); `hindsight verify` recomputes it from the stored configuration.
#pragma once

#include <hindsight/problems/app/config.h>

#include <nlohmann/json.hpp>

#include <string>

namespace hindsight {

class Communicator;

/// "fnv1a64:<16 hex digits>" of the configuration's canonical JSON text (toJson(config).dump()).
std::string configurationFingerprint(const Config& config);
/// The same for a configuration stored as JSON; throws std::invalid_argument when it is not one.
std::string configurationFingerprint(const std::string& configurationJson);

/// The fields in which two run descriptions differ, as "section.field" (or "section" for a value
/// that is not an object, e.g. scenarios), in key order; empty when equal. Keys present in only one
/// of them count as differing.
std::vector<std::string> differingFields(const nlohmann::json& a, const nlohmann::json& b);

/// Collective: every rank passes its configuration and run options (a JSON object of the options
/// that must agree). Returns normally on every rank when all agree; otherwise throws
/// std::invalid_argument on every rank naming the differing fields and ranks. One process: returns.
void agreeOnConfiguration(const Communicator& world, const Config& config, const nlohmann::json& runOptions);

}  // namespace hindsight
