// What the C API's opaque handles (dvs/dvs.h) hold: the C++ objects of the embedding API.
#pragma once
#include <memory>
#include <string>

#include "dvs/context.hpp"
#include "dvs/depth_frames.hpp"
#include "dvs/dvs.h"
#include "dvs/job.hpp"
#include "dvs/scene.hpp"

struct dvs_context {
  std::unique_ptr<dvs::Context> context;
};

struct dvs_scene {
  std::unique_ptr<dvs::PointCloudScene> scene;
};

struct dvs_depth_estimator {
  std::unique_ptr<dvs::DepthEstimator> estimator;
};

struct dvs_job {
  dvs::Job job;
  std::string kind;  // "render", "pipeline" or "depth": which result getter dvs_job_result asks
};
