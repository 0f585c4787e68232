#pragma once

// The calibration blocks of the block table (sensors/calibration_blocks.h) as the problem
// file, the dataset's sensors.yaml and the result's calibration file hold them, and the
// blocks an offline calibration estimates (docs/calibration.md, "Observability and
// uncertainty"): each with its prior (the problem's sigma in prior mode, else the dataset's
// stated nominal uncertainty, else the options' weak default) and its observability limits.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace pipeline {

// What the problem and sensors.yaml say about one block, in file units (degrees for a
// rotation, else SI), one value per tangent direction.
struct BlockSetting {
  io::BlockMode mode = io::BlockMode::kFixed;
  Eigen::VectorXd prior_sigma;                   // the problem's; set in prior mode
  std::optional<Eigen::VectorXd> nominal_sigma;  // sensors.yaml's, when it states one
};
BlockSetting SettingOf(sensors::CalibrationBlockId id, const io::ProblemCalibration& problem,
                       const io::CalibrationUncertainty& nominal);

// File units to tangent units: degrees to radians for a rotation, else 1.
double FileToTangent(const sensors::CalibrationBlockInfo& block);

// Whether the sensor of `block` takes part: the wheels with use_wheel, GNSS with use_gnss.
// LiDAR blocks always may (a problem without the LiDAR fixes them).
bool SensorUsed(const sensors::CalibrationBlockInfo& block, bool use_wheel, bool use_gnss);

// The blocks of `problem` that are estimated, in table order, their data pointing into
// `calibration`; the wheel blocks only with use_wheel, the lever arm only with use_gnss, one
// radius for both wheels with wheel_radius_shared.
std::vector<estimation::EstimatedBlock> EstimatedBlocks(const io::Problem& problem,
                                                        const io::SensorsConfig& sensors,
                                                        const OfflineCalibrationOptions& options,
                                                        bool use_wheel, bool use_gnss,
                                                        sensors::Calibration* calibration);

// The blocks of `problem` held fixed, as EstimatedBlocks describes them: their prior the
// nominal value under the sigma an estimate would take (sensors.yaml's, else the weak
// default), for FixedDirectionsTheDataMove.
std::vector<estimation::EstimatedBlock> FixedBlocks(const io::Problem& problem,
                                                    const io::SensorsConfig& sensors,
                                                    const OfflineCalibrationOptions& options,
                                                    bool use_wheel, bool use_gnss,
                                                    sensors::Calibration* calibration);

// Block `id`'s weak default prior sigma in file units (degrees for a rotation), for a block whose
// sigma neither the problem nor sensors.yaml states. The online estimator takes the same one.
double DefaultPriorSigma(sensors::CalibrationBlockId id, const io::SensorsConfig& sensors,
                         const OfflineCalibrationOptions& options);

// Three times the widest prior sigma (degrees) of rotation block `rotation` among `blocks`:
// how far a nominal rotation may plausibly lie from the truth. Infinity when it is not among
// them.
double ThreeSigmaPriorDeg(const std::vector<estimation::EstimatedBlock>& blocks,
                          sensors::CalibrationBlockId rotation);

// ThreeSigmaPriorDeg of the IMU mount q_I_V in `problem` with the
// nominal uncertainty of `sensors`: a nominal mount further than this from the data's is
// no guess. Infinity when the problem does not estimate the mount.
double MaxNominalMountDeg(const io::Problem& problem, const io::SensorsConfig& sensors,
                          const OfflineCalibrationOptions& options);

// Sets block `id`'s sigma (tangent units, one per direction) in `uncertainty`, and its
// observability flags when `observable` is given.
void SetUncertainty(sensors::CalibrationBlockId id, const Eigen::VectorXd& sigma,
                    const std::vector<bool>* observable, io::CalibrationUncertainty* uncertainty);

// Sigma and observability flags of every block in `uncertainty`.
void FillUncertainty(const std::vector<estimation::EstimatedBlock>& blocks,
                     const estimation::BlockObservability& observability,
                     io::CalibrationUncertainty* uncertainty);

}  // namespace pipeline
}  // namespace autocal
