#include <hindsight/problems/topopt/solid_motion_export.h>

#include <hindsight/storage/atomic_file.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace hindsight {
namespace {

// The half model's nodes per layer of the whole body: layer K of 0..layers() is node layer |K - nz| of
// the model with the sign of z (symmetry), or K itself.
struct NodeLayer {
  int k;
  double zSign;
};

NodeLayer modelLayer(const BoxDensityField& field, int layer) {
  if (!field.midPlaneSymmetry) return {layer, 1.0};
  return layer >= field.nz ? NodeLayer{layer - field.nz, 1.0} : NodeLayer{field.nz - layer, -1.0};
}

Eigen::Index modelDofCount(const BoxDensityField& field) {
  return 3 * static_cast<Eigen::Index>(field.nx + 1) * (field.ny + 1) * (field.nz + 1);
}

void checkModes(const BoxDensityField& field, ConstMatrixRef modes, Eigen::Index q) {
  if (field.nx < 1 || field.ny < 1 || field.nz < 1)
    throw std::invalid_argument("solid motion: the field has no elements");
  if (modes.rows() != modelDofCount(field) || modes.cols() != q)
    throw std::invalid_argument("solid motion: the modes are " + std::to_string(modes.rows()) + " x " +
                                std::to_string(modes.cols()) + ", expected " +
                                std::to_string(modelDofCount(field)) + " x " + std::to_string(q) +
                                " (the solid's DOFs x the modal coordinates)");
}

}  // namespace

MemberMotion recordMemberMotion(const PistonRod& rod, ConstVectorRef modelDesign, int frames) {
  if (frames < 2) throw std::invalid_argument("--frames " + std::to_string(frames) + " must be >= 2");
  const IntegratorOptions options = rod.integratorOptions();
  MemberMotion motion;
  std::vector<Vector> poses, modal;
  // Frame k is the first step at or after t0 + k (t1 - t0) / (frames - 1); the tolerance absorbs the
  // round-off of the grid's times.
  const double span = options.t1 - options.t0;
  PistonRod::Request request;
  request.psi1Gradient = false;
  request.psi2 = false;
  request.psi2Gradient = false;
  request.motion = [&](double t, ConstVectorRef pose, ConstVectorRef q) {
    const int k = static_cast<int>(motion.times.size());
    if (k >= frames || t < options.t0 + span * k / (frames - 1) - 1e-9 * span) return;
    motion.times.push_back(t);
    poses.emplace_back(pose);
    modal.emplace_back(q);
  };
  PistonRodEvaluation evaluation = rod.evaluate(modelDesign, request);
  motion.poses.resize(3, static_cast<Eigen::Index>(poses.size()));
  motion.modal.resize(evaluation.modes.cols(), static_cast<Eigen::Index>(modal.size()));
  for (std::size_t k = 0; k < poses.size(); ++k) {
    motion.poses.col(static_cast<Eigen::Index>(k)) = poses[k];
    motion.modal.col(static_cast<Eigen::Index>(k)) = modal[k];
  }
  motion.modes = std::move(evaluation.modes);
  motion.psi1 = evaluation.psi1;
  return motion;
}

Matrix solidFramePoints(const BoxDensityField& field, ConstMatrixRef modes, ConstVectorRef pose,
                        ConstVectorRef q, double scale, Matrix* displacement) {
  checkModes(field, modes, q.size());
  if (pose.size() != 3) throw std::invalid_argument("solidFramePoints: the pose has 3 entries (x, y, beta)");
  const int nx = field.nx, ny = field.ny, layers = field.layers();
  const Vector u = modes * q;
  const double c = std::cos(pose(2)), s = std::sin(pose(2));
  // The grid's sizes in metres; z from the mid-plane of the whole body.
  const double wx = 1e-3 * field.cellWidthMm, wy = 1e-3 * field.cellHeightMm, wz = 1e-3 * field.cellDepthMm;
  const double height = ny * wy, thickness = layers * wz;
  const Eigen::Index count = static_cast<Eigen::Index>(nx + 1) * (ny + 1) * (layers + 1);
  Matrix points(3, count);
  if (displacement != nullptr) displacement->resize(3, count);
  Eigen::Index column = 0;
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int layer = 0; layer <= layers; ++layer, ++column) {
        const NodeLayer image = modelLayer(field, layer);
        const Eigen::Index node = (static_cast<Eigen::Index>(i) * (ny + 1) + j) * (field.nz + 1) + image.k;
        const double ux = scale * u(3 * node), uy = scale * u(3 * node + 1),
                     uz = scale * image.zSign * u(3 * node + 2);
        const double x = i * wx + ux, y = -0.5 * height + j * wy + uy, z = -0.5 * thickness + layer * wz + uz;
        points.col(column) << 1e3 * (pose(0) + c * x - s * y), 1e3 * (pose(1) + s * x + c * y), 1e3 * z;
        if (displacement != nullptr)
          displacement->col(column) << 1e3 * (c * ux - s * uy), 1e3 * (s * ux + c * uy), 1e3 * uz;
      }
    }
  }
  return points;
}

double largestDisplacement(const BoxDensityField& field, const MemberMotion& motion) {
  checkModes(field, motion.modes, motion.modal.rows());
  double largest = 0.0;
  for (Eigen::Index k = 0; k < motion.modal.cols(); ++k) {
    const Vector u = motion.modes * motion.modal.col(k);
    for (Eigen::Index node = 0; node < u.size() / 3; ++node)
      largest = std::max(largest, u.segment<3>(3 * node).norm());
  }
  return largest;
}

double defaultMagnification(double largestDisplacementM, double rodLengthM) {
  if (!(largestDisplacementM > 0.0)) return 1.0;
  const double bound = 0.05 * rodLengthM / largestDisplacementM;
  double decade = std::pow(10.0, std::floor(std::log10(bound)));
  for (double mantissa : {5.0, 2.0, 1.0}) {
    if (mantissa * decade <= bound) return mantissa * decade;
  }
  return decade / 2.0;  // bound just below a power of ten by round-off of log10
}

std::string magnificationLabel(double scale) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", scale);
  return buffer;
}

std::string writeSolidMotion(const std::string& directory, const BoxDensityField& field,
                             const MemberMotion& motion, double scale, bool overwrite) {
  namespace fs = std::filesystem;
  if (!(scale > 0.0) || !std::isfinite(scale))
    throw std::invalid_argument("--scale " + std::to_string(scale) + " must be > 0");
  if (!overwrite && fs::exists(directory))
    throw std::invalid_argument(directory + " exists; use --force to overwrite it");
  checkModes(field, motion.modes, motion.modal.rows());
  const fs::path target(directory);
  const fs::path temporary =
      target.parent_path() / (target.filename().string() + ".tmp-" + std::to_string(::getpid()));
  std::error_code error;
  fs::remove_all(temporary, error);
  if (!fs::create_directories(temporary, error) && error)
    throw StorageError("cannot create " + temporary.string() + ": " + error.message());
  const std::string label = magnificationLabel(scale);
  const std::string pvdName = "motion_x" + label + ".pvd";
  try {
    std::string collection =
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" "
        "byte_order=\"LittleEndian\">\n<Collection>\n";
    for (Eigen::Index k = 0; k < motion.modal.cols(); ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04ld.vtu", static_cast<long>(k));
      Matrix displacement;
      const Matrix points = solidFramePoints(field, motion.modes, motion.poses.col(k), motion.modal.col(k),
                                             scale, &displacement);
      writeDensityVtu((temporary / name).string(), field, points, {{"displacement_x" + label, displacement}});
      char time[40];
      std::snprintf(time, sizeof time, "%.17g", motion.times[static_cast<std::size_t>(k)]);
      collection +=
          std::string("<DataSet timestep=\"") + time + "\" group=\"\" part=\"0\" file=\"" + name + "\"/>\n";
    }
    collection += "</Collection>\n</VTKFile>\n";
    writeBytesAtomically((temporary / pvdName).string(), collection.data(), collection.size(),
                         "the ParaView collection");
    // An existing directory is moved aside first and removed once the new one is in place.
    const fs::path old =
        target.parent_path() / (target.filename().string() + ".old-" + std::to_string(::getpid()));
    const bool replace = fs::exists(target);
    if (replace) {
      fs::remove_all(old, error);
      fs::rename(target, old, error);
      if (error) throw StorageError("cannot move " + target.string() + " aside: " + error.message());
    }
    fs::rename(temporary, target, error);
    if (error) {
      if (replace) fs::rename(old, target, error);
      throw StorageError("cannot rename " + temporary.string() + " to " + target.string());
    }
    if (replace) fs::remove_all(old, error);
  } catch (...) {
    fs::remove_all(temporary, error);
    throw;
  }
  return (target / pvdName).string();
}

}  // namespace hindsight
