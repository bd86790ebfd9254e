#include "textile_handling/recognition/camera_geometry.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/vision/mask_cv.h"

namespace textile_handling {
namespace recognition {

namespace {

constexpr double kRadToDeg = 180.0 / kPi;

[[noreturn]] void geometryError(const std::string& what) {
  throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, what);
}

std::string vecText(const Vec3& v) {
  std::ostringstream os;
  os << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return os.str();
}

void validateOptions(const CameraGeometryOptions& o) {
  auto bad = [](double v, double lo, double hi) { return !(v >= lo && v <= hi); };
  if (bad(o.max_elevation_deg, 0, 89) || bad(o.max_tilt_deg, 0, 89) || bad(o.max_roll_deg, 0, 89))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions,
                           "geometry: max_elevation_deg, max_tilt_deg and max_roll_deg must lie in [0, 89]");
  if (bad(o.min_depth_m, 0, 1e6) || bad(o.min_horizontal_distance_m, 0, 1e6) ||
      bad(o.max_hold_pixel_outside_px, 0, 1e9) || bad(o.rectify_epsilon_deg, 0, 10))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions,
                           "geometry: distances, the pixel margin and the rectification epsilon must be finite and >= 0");
  if (bad(o.min_fov_deg, 0, 179) || bad(o.max_fov_deg, o.min_fov_deg, 179.9) || bad(o.max_aspect, 1, 100) ||
      bad(o.max_principal_point_outside, 0, 100) || bad(o.max_hold_distance_m, o.min_depth_m, 1e6))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions,
                           "geometry: need 0 <= min_fov_deg <= max_fov_deg < 180, max_aspect in [1, 100], "
                           "max_principal_point_outside in [0, 100], max_hold_distance_m >= min_depth_m");
}

// A camera_info that no real camera has (docs/recognition.md "Evidence"): the fields of view, the pixel
// aspect and the principal point against CameraGeometryOptions.
void checkPlausibleIntrinsics(const vision::PinholeIntrinsics& k, const CameraGeometryOptions& o) {
  const double fov_x = 2 * std::atan(0.5 * k.width / k.fx) * kRadToDeg;
  const double fov_y = 2 * std::atan(0.5 * k.height / k.fy) * kRadToDeg;
  for (const auto& [fov, axis] : {std::make_pair(fov_x, "horizontal"), std::make_pair(fov_y, "vertical")})
    if (!(fov >= o.min_fov_deg && fov <= o.max_fov_deg)) {
      std::ostringstream os;
      os << "implausible camera: fx = " << k.fx << ", fy = " << k.fy << " px on a " << k.width << " x " << k.height
         << " image give a " << axis << " field of view of " << fov << " deg (plausible " << o.min_fov_deg << ".."
         << o.max_fov_deg << " deg)";
      geometryError(os.str());
    }
  if (!(k.fy / k.fx <= o.max_aspect && k.fx / k.fy <= o.max_aspect))
    geometryError("implausible camera: fy / fx = " + std::to_string(k.fy / k.fx) + " (plausible 1/" +
                  std::to_string(o.max_aspect) + ".." + std::to_string(o.max_aspect) + ")");
  const double mx = o.max_principal_point_outside * k.width, my = o.max_principal_point_outside * k.height;
  if (!(k.cx >= -mx && k.cx <= k.width + mx && k.cy >= -my && k.cy <= k.height + my))
    geometryError("implausible camera: principal point (" + std::to_string(k.cx) + ", " + std::to_string(k.cy) +
                  ") lies more than " + std::to_string(o.max_principal_point_outside) +
                  " image sizes outside the image");
}

}  // namespace

double wrapDegrees(double a) {
  a = std::fmod(a, 360.0);
  if (a < 0) a += 360.0;
  return a >= 360.0 ? 0.0 : a;
}

double azimuthOfDirection(const Vec3& d) { return wrapDegrees(std::atan2(-d.x(), d.y()) * kRadToDeg); }

Mat3 rotationZ(double deg) {
  const double a = deg * kPi / 180.0, c = std::cos(a), s = std::sin(a);
  Mat3 r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return r;
}

HoldGeometry computeHoldGeometry(const vision::PinholeIntrinsics& k, const Vec3& hold, const Vec3& up_in,
                                 const std::optional<Vec3>& heading, const CameraGeometryOptions& o) {
  validateOptions(o);
  if (!std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) || !std::isfinite(k.cy))
    geometryError("camera intrinsics are not finite (fx, fy, cx, cy must be numbers)");
  if (!(k.fx > 0) || !(k.fy > 0)) geometryError("camera focal lengths fx, fy must be > 0");
  if (k.width <= 0 || k.height <= 0) geometryError("camera image size (width, height) must be > 0");
  checkPlausibleIntrinsics(k, o);
  if (!hold.allFinite()) geometryError("hold point " + vecText(hold) + " is not finite");
  if (!(hold.norm() <= o.max_hold_distance_m))
    geometryError("hold point " + vecText(hold) + " is farther than " + std::to_string(o.max_hold_distance_m) +
                  " m from the camera");
  if (!up_in.allFinite() || !(up_in.norm() > 1e-9)) geometryError("up vector " + vecText(up_in) + " is zero or not finite");
  if (heading && !heading->allFinite()) geometryError("heading reference " + vecText(*heading) + " is not finite");
  if (!(hold.z() > 0)) geometryError("hold point " + vecText(hold) + " is behind the camera (z <= 0 in the optical frame)");
  if (hold.z() < o.min_depth_m)
    geometryError("hold point " + vecText(hold) + " is closer than " + std::to_string(o.min_depth_m) +
                  " m in front of the camera");

  HoldGeometry g;
  g.intrinsics = k;
  g.hold_camera = hold;
  const Vec3 up = up_in.normalized();
  g.up_camera = up;
  g.hold_depth_m = hold.z();
  g.hold_pixel = Vec2(k.fx * hold.x() / hold.z() + k.cx, k.fy * hold.y() / hold.z() + k.cy);
  g.metres_per_pixel = Vec2(hold.z() / k.fx, hold.z() / k.fy);
  const double out_x = std::max({0.0, -0.5 - g.hold_pixel.x(), g.hold_pixel.x() - (k.width - 0.5)});
  const double out_y = std::max({0.0, -0.5 - g.hold_pixel.y(), g.hold_pixel.y() - (k.height - 0.5)});
  if (std::max(out_x, out_y) > o.max_hold_pixel_outside_px) {
    std::ostringstream os;
    os << "hold point projects to pixel (" << g.hold_pixel.x() << ", " << g.hold_pixel.y() << "), more than "
       << o.max_hold_pixel_outside_px << " px outside the " << k.width << " x " << k.height << " image";
    geometryError(os.str());
  }

  const double vert = hold.dot(up);
  const Vec3 horiz = hold - vert * up;
  g.horizontal_distance_m = horiz.norm();
  g.elevation_deg = std::asin(std::clamp(vert / hold.norm(), -1.0, 1.0)) * kRadToDeg;
  if (g.horizontal_distance_m < std::max(o.min_horizontal_distance_m, 1e-6)) {
    std::ostringstream os;
    os << "hold point is only " << g.horizontal_distance_m << " m from the camera horizontally (minimum "
       << o.min_horizontal_distance_m << " m): the camera must look at the hanging textile from the side";
    geometryError(os.str());
  }
  if (std::abs(g.elevation_deg) > o.max_elevation_deg) {
    std::ostringstream os;
    os << "the camera sees the hold point " << std::abs(g.elevation_deg) << " deg " << (vert > 0 ? "above" : "below")
       << " the horizontal (limit " << o.max_elevation_deg
       << " deg): the stored silhouettes are horizontal views";
    geometryError(os.str());
  }
  g.tilt_deg = std::asin(std::clamp(up.z(), -1.0, 1.0)) * kRadToDeg;
  g.roll_deg = std::asin(std::clamp(up.x(), -1.0, 1.0)) * kRadToDeg;
  if (std::abs(g.tilt_deg) > o.max_tilt_deg || std::abs(g.roll_deg) > o.max_roll_deg) {
    std::ostringstream os;
    os << "camera tilt " << g.tilt_deg << " deg / roll " << g.roll_deg << " deg exceed the limits ("
       << o.max_tilt_deg << " / " << o.max_roll_deg << " deg); is the up vector given in the optical frame?";
    geometryError(os.str());
  }

  // Virtual horizontal camera V looking at the hold axis.
  const Vec3 zv = horiz / g.horizontal_distance_m;
  const Vec3 yv = -up;
  const Vec3 xv = yv.cross(zv).normalized();
  g.rotation_camera_virtual.col(0) = xv;
  g.rotation_camera_virtual.col(1) = yv;
  g.rotation_camera_virtual.col(2) = zv;
  const double cos_angle = std::clamp((g.rotation_camera_virtual.trace() - 1.0) / 2.0, -1.0, 1.0);
  g.rectified = std::acos(cos_angle) * kRadToDeg > o.rectify_epsilon_deg;
  g.camera_height_m = -vert;
  g.virtual_hold_pixel = Vec2(k.cx, k.cy + k.fy * g.camera_height_m / g.horizontal_distance_m);
  g.virtual_metres_per_pixel = Vec2(g.horizontal_distance_m / k.fx, g.horizontal_distance_m / k.fy);
  if (!g.rectified) g.virtual_hold_pixel = g.hold_pixel;  // identical up to rounding

  // Hold frame H.
  Vec3 xh = xv;
  if (heading) {
    const Vec3 hh = *heading - heading->dot(up) * up;
    if (!(hh.norm() > 1e-3 * heading->norm()) || !(heading->norm() > 1e-12))
      geometryError("heading reference " + vecText(*heading) + " is (nearly) vertical or zero; it must have a horizontal part");
    xh = hh.normalized();
    g.has_heading = true;
  }
  const Vec3 zh = up;
  const Vec3 yh = zh.cross(xh).normalized();
  g.rotation_camera_hold.col(0) = xh;
  g.rotation_camera_hold.col(1) = yh;
  g.rotation_camera_hold.col(2) = zh;
  g.view_direction_hold = g.rotation_camera_hold.transpose() * zv;
  g.view_direction_hold.z() = 0;
  g.view_direction_hold.normalize();
  g.camera_azimuth_deg = azimuthOfDirection(g.view_direction_hold);
  return g;
}

cv::Mat rectifyMaskForFrame(const cv::Mat& mask, const HoldGeometry& g, const vision::CanonicalFrame& frame,
                            const CanonicalisationOptions& o, cv::Point* origin) {
  if (mask.empty()) throw RecognitionError(RecognitionErrorCode::kInvalidImage, "the textile mask is empty");
  if (mask.type() != CV_8UC1)
    throw RecognitionError(RecognitionErrorCode::kInvalidImage,
                           "the textile mask must be CV_8UC1, got type " + std::to_string(mask.type()));
  if (mask.cols != g.intrinsics.width || mask.rows != g.intrinsics.height) {
    std::ostringstream os;
    os << "the mask is " << mask.cols << " x " << mask.rows << " px, the camera info says " << g.intrinsics.width
       << " x " << g.intrinsics.height;
    throw RecognitionError(RecognitionErrorCode::kInvalidImage, os.str());
  }
  try {
    frame.validate();
  } catch (const std::exception& e) {
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, std::string("canonical frame: ") + e.what());
  }
  if (o.max_canvas_px < 16)
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "max_canvas_px must be >= 16");
  const double sx = frame.metres_per_pixel / g.virtual_metres_per_pixel.x();
  const double sy = frame.metres_per_pixel / g.virtual_metres_per_pixel.y();
  const Vec2 h = g.virtual_hold_pixel;
  const double xlo = h.x() + 0.5 - 0.5 * frame.width_px * sx, xhi = h.x() + 0.5 + 0.5 * frame.width_px * sx;
  const double ylo = h.y() + 0.5 - frame.top_margin_px * sy, yhi = h.y() + 0.5 + (frame.height_px - frame.top_margin_px) * sy;
  const double ox_d = std::floor(xlo) - 1, oy_d = std::floor(ylo) - 1;
  const double cw_d = std::ceil(xhi) - ox_d + 1, ch_d = std::ceil(yhi) - oy_d + 1;
  if (!(cw_d <= o.max_canvas_px && ch_d <= o.max_canvas_px) || !(std::abs(ox_d) < 1e8 && std::abs(oy_d) < 1e8)) {
    std::ostringstream os;
    os << "the canonical window covers " << cw_d << " x " << ch_d << " camera pixels (limit " << o.max_canvas_px
       << "): the camera is too close or its focal length too large for this canonical frame";
    geometryError(os.str());
  }
  const int ox = static_cast<int>(ox_d), oy = static_cast<int>(oy_d);
  const int cw = static_cast<int>(cw_d), ch = static_cast<int>(ch_d);
  cv::Mat canvas(ch, cw, CV_8UC1, cv::Scalar(0));
  if (!g.rectified) {
    const cv::Rect src_rect = cv::Rect(ox, oy, cw, ch) & cv::Rect(0, 0, mask.cols, mask.rows);
    if (src_rect.area() > 0) {
      cv::Mat src = mask(src_rect);
      cv::Mat dst = canvas(cv::Rect(src_rect.x - ox, src_rect.y - oy, src_rect.width, src_rect.height));
      cv::compare(src, 0, dst, cv::CMP_NE);
    }
  } else {
    // Each canvas pixel (V image) looks along a ray of V; rotate it into C and project with K.
    const auto& k = g.intrinsics;
    const Mat3& r = g.rotation_camera_virtual;
    cv::Mat map_x(ch, cw, CV_32FC1), map_y(ch, cw, CV_32FC1);
    for (int j = 0; j < ch; ++j) {
      float* mx = map_x.ptr<float>(j);
      float* my = map_y.ptr<float>(j);
      for (int i = 0; i < cw; ++i) {
        const Vec3 ray_v((ox + i - k.cx) / k.fx, (oy + j - k.cy) / k.fy, 1.0);
        const Vec3 ray_c = r * ray_v;
        if (ray_c.z() <= 1e-9) {
          mx[i] = my[i] = -1e6f;
          continue;
        }
        mx[i] = static_cast<float>(k.fx * ray_c.x() / ray_c.z() + k.cx);
        my[i] = static_cast<float>(k.fy * ray_c.y() / ray_c.z() + k.cy);
      }
    }
    cv::Mat binary;
    cv::compare(mask, 0, binary, cv::CMP_NE);  // 0 / 255
    cv::Mat warped;
    cv::remap(binary, warped, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::compare(warped, 127, canvas, cv::CMP_GT);
  }
  if (o.clear_above_hold_m >= 0) {
    const double limit = h.y() - o.clear_above_hold_m / g.virtual_metres_per_pixel.y();
    for (int j = 0; j < ch; ++j)
      if (oy + j + 0.5 <= limit) canvas.row(j).setTo(0);
  }
  if (origin) *origin = cv::Point(ox, oy);
  return canvas;
}

vision::BitMask canonicaliseObservationMask(const cv::Mat& mask, const HoldGeometry& g,
                                            const vision::CanonicalFrame& frame, const CanonicalisationOptions& o) {
  cv::Point origin;
  const cv::Mat canvas = rectifyMaskForFrame(mask, g, frame, o, &origin);
  const Vec2 hold_canvas = g.virtual_hold_pixel - Vec2(origin.x, origin.y);
  try {
    return vision::canonicaliseCameraMask(canvas, hold_canvas, g.virtual_metres_per_pixel, frame);
  } catch (const std::invalid_argument& e) {
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, std::string("canonicalisation: ") + e.what());
  }
}

}  // namespace recognition
}  // namespace textile_handling
