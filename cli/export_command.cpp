// `hindsight export DIR [--iso 0.5] [--iteration K] [--out STEM] [--force]`: the geometry of a design of
// an optimization run as STEM.svg and STEM.dxf (2-D outline, millimetres) and STEM.stl (the outline
// extruded by the rod thickness, watertight); problems/topopt/geometry_export.h. The design is the
// element density field the model saw in iteration K (default: the last one) of DIR/results.h5, read
// with every check of a resume. STEM defaults to DIR/design_final (finished run, last iteration) or
// DIR/design_iter_K; existing files are overwritten only with --force. Exit 2 for bad input, 3 for a
// corrupted results file or a failed write. The solid member's design (rod.elementsThroughThickness >= 1)
// goes to STEM.stl (the surface of the elements at or above the iso density) and STEM.vtu (the densities
// for ParaView); with --motion [--frames N] [--scale S] instead to STEM_motion/, the ParaView time series
// of the member over the motion, deformed by S times its modal displacement
// (problems/topopt/solid_motion_export.h).
#include <hindsight/problems/topopt/geometry_export.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/problems/topopt/solid_motion_export.h>
#include <hindsight/problems/topopt/topology_optimizer.h>
#include "commands.h"

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>

namespace hindsight::cli {
namespace {

struct ExportSettings {
  std::string directory;
  double iso = 0.5;
  int iteration = -1;  // -1: not given, the last
  CLI::Option* iterationOption = nullptr;
  std::string stem;
  bool force = false;
  bool motion = false;
  int frames = 61;
  double scale = 0.0;  // 0: not given, the default magnification
  CLI::Option* scaleOption = nullptr;
};

// --motion: the final design simulated once more (values only), `frames` frames of the member in the
// global plane written to DIRECTORY as a ParaView time series.
int exportMotion(const ExportSettings& s, const TopologyOptimizer& optimizer, const BoxDensityField& field,
                 const ResultsData& data, const std::string& directory) {
  if (s.frames < 2) throw std::invalid_argument("--frames " + std::to_string(s.frames) + " must be >= 2");
  if (s.scaleOption->count() > 0 && !(s.scale > 0.0))
    throw std::invalid_argument("--scale " + std::to_string(s.scale) + " must be > 0");
  if (!s.force && std::filesystem::exists(directory))
    throw std::invalid_argument(directory + " exists; use --force to overwrite it");
  const int iteration = data.history.back().iteration;
  const MemberMotion motion = recordMemberMotion(
      optimizer.rod(), optimizer.modelDesign(optimizer.designToEvaluate(data.state), iteration), s.frames);
  const double largest = largestDisplacement(field, motion);
  const double scale =
      s.scaleOption->count() > 0 ? s.scale : defaultMagnification(largest, optimizer.config().rod.length);
  const std::string pvd = writeSolidMotion(directory, field, motion, scale, s.force);
  std::cout << "psi1 " << std::setprecision(17) << motion.psi1 << std::setprecision(6) << ", "
            << motion.times.size() << " frames over [" << motion.times.front() << ", " << motion.times.back()
            << "] s, largest displacement " << 1e3 * largest << " mm, drawn magnified "
            << magnificationLabel(scale) << " times\n"
            << "wrote " << pvd << '\n';
  return 0;
}

// The solid member (rod.elementsThroughThickness >= 1): the surface of the elements at or above the iso
// density as STEM.stl and the densities as STEM.vtu (ParaView), both of the whole body. results.h5 keeps
// the design variables of the final design (the optimizer's state: TopologyOptimizer::designToEvaluate),
// so a finished run's last iteration is what can be exported; the model's densities follow from them by
// the run's filter and projection.
int exportSolid(const ExportSettings& s, const ResultsData& data, const Config& config, int k,
                const std::string& stem) {
  namespace fs = std::filesystem;
  const int last = static_cast<int>(data.densities.size()) - 1;
  if (!data.finished || k != last)
    throw std::invalid_argument(
        "export: the solid member's design is kept for the final iteration of a "
        "finished run only (--iteration " +
        std::to_string(last) + " of a finished run)");
  for (const char* extension : {".stl", ".vtu"}) {
    if (!s.motion && !s.force && fs::exists(stem + extension))
      throw std::invalid_argument(stem + extension + " exists; use --force to overwrite it");
  }
  const TopologyOptimizer optimizer(config);
  // The final evaluation's design: a run that reached optimization.iterations ends on its best feasible
  // design, which is not the state's last MMA iterate.
  const BoxDensityField field =
      optimizer.solidField(optimizer.designToEvaluate(data.state), data.history.back().iteration);
  if (s.motion) return exportMotion(s, optimizer, field, data, stem + "_motion");
  const std::vector<std::string> written = exportSolidGeometry(stem, field, s.iso);
  const long above = (field.values.array() >= s.iso).count();
  std::cout << "iteration " << k << ", iso " << s.iso << ": " << above << " of " << field.values.size()
            << " modelled elements at or above it\n";
  for (const std::string& file : written) std::cout << "wrote " << file << '\n';
  return 0;
}

int runExport(const ExportSettings& s) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(s.directory))
    throw std::invalid_argument("export: '" + s.directory + "' is not a directory");
  if (!(s.iso > 0.0 && s.iso < 1.0))
    throw std::invalid_argument("--iso " + std::to_string(s.iso) + " must be in (0, 1)");
  const std::string path = (fs::path(s.directory) / "results.h5").string();
  if (!fs::exists(path)) throw std::invalid_argument("export: '" + path + "' does not exist");
  const ResultsData data = readResultsFile(path);  // StorageError (exit 3) when corrupted
  const int rows = static_cast<int>(data.densities.size());
  if (rows == 0) throw std::invalid_argument("export: " + path + " holds no iteration yet");
  const bool given = s.iterationOption->count() > 0;
  const int k = given ? s.iteration : rows - 1;
  if (k < 0 || k >= rows) {  // a negative K given is an error, not "the last"
    throw std::invalid_argument("--iteration " + std::to_string(s.iteration) + " must be in [0, " +
                                std::to_string(rows - 1) + "] (the iterations stored in " + path + ")");
  }
  const Config config = configFromJson(nlohmann::json::parse(data.configurationJson));
  const std::string stem =
      !s.stem.empty()
          ? s.stem
          : (fs::path(s.directory) /
             (data.finished && k == rows - 1 ? "design_final" : "design_iter_" + std::to_string(k)))
                .string();
  if (config.rod.isSolid()) return exportSolid(s, data, config, k, stem);
  if (s.motion)
    throw std::invalid_argument(
        "export: --motion needs the solid member (rod.elementsThroughThickness >= 1); this run is the plate");
  for (const char* extension : {".svg", ".dxf", ".stl"}) {
    if (!s.force && fs::exists(stem + extension))
      throw std::invalid_argument(stem + extension + " exists; use --force to overwrite it");
  }
  DensityField field;
  field.nx = data.nx;
  field.ny = data.ny;
  field.values = data.densities[static_cast<std::size_t>(k)];
  field.cellWidthMm = 1000.0 * config.rod.length / data.nx;
  field.cellHeightMm = 1000.0 * config.rod.height / data.ny;
  const std::vector<std::string> written = exportGeometry(stem, field, s.iso, 1000.0 * config.rod.thickness);
  const Outline outline = contourOutline(field, s.iso);
  std::cout << "iteration " << k << ", iso " << s.iso << ": " << outline.loops.size()
            << " outline loops, area " << outline.area() << " mm^2 of "
            << field.nx * field.cellWidthMm * field.ny * field.cellHeightMm << " mm^2\n";
  for (const std::string& file : written) std::cout << "wrote " << file << '\n';
  return 0;
}

}  // namespace

void registerExport(CLI::App& app) {
  auto s = std::make_shared<ExportSettings>();
  CLI::App* command = app.add_subcommand(
      "export",
      "Geometry of a design of an optimization run: outline (SVG, DXF, mm) and extruded solid (STL); of the "
      "solid member its surface (STL) and densities (VTU)");
  command->add_option("directory", s->directory, "result directory (of hindsight optimize --out)")
      ->required();
  command->add_option("--iso", s->iso, "density of the contour, in (0, 1)")->capture_default_str();
  s->iterationOption =
      command->add_option("--iteration", s->iteration, "iteration K of the history (default: the last)");
  command->add_option("--out", s->stem, "output stem (default DIR/design_final or DIR/design_iter_K)");
  command->add_flag("--force", s->force, "overwrite existing files");
  command->add_flag(
      "--motion", s->motion,
      "the solid member over the motion instead: a ParaView time series (STEM_motion/"
      "motion_x<scale>.pvd, one .vtu per frame) of the final design in the global plane, deformed "
      "by its magnified modal displacement");
  command->add_option("--frames", s->frames, "with --motion: frames equally spaced over [0, t1], >= 2")
      ->capture_default_str();
  s->scaleOption = command->add_option(
      "--scale", s->scale,
      "with --motion: magnification of the displacement, > 0 (default: 1, 2 or 5 times a power of ten, the "
      "largest keeping it <= 5 % of the rod length)");
  commands().push_back({command, [s] { return guarded([&] { return runExport(*s); }); }});
}

}  // namespace hindsight::cli
