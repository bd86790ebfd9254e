#include "textile_handling/db/simulation_outcome_codec.h"

#include <cstring>
#include <utility>

#include "little_endian.h"
#include "textile_handling/db/blob_codec.h"

namespace textile_handling {
namespace db {

namespace {

constexpr char kMagic[4] = {'T', 'H', 'S', 'O'};
/// Largest string or byte field accepted when decoding: a sane parameter or failure text is far shorter,
/// and a mask blob of the largest side is 8 MB.
constexpr std::uint32_t kMaxField = 64u << 20;
constexpr std::uint32_t kMaxViews = 100000;

class ByteWriter {
 public:
  template <typename T>
  void put(T v) {
    out_.resize(out_.size() + sizeof(T));
    internal::putLE<T>(out_.data() + out_.size() - sizeof(T), v);
  }
  void f64(double v) {
    out_.resize(out_.size() + 8);
    internal::putDouble(out_.data() + out_.size() - 8, v);
  }
  void bytes(const std::uint8_t* p, std::size_t n) {
    put<std::uint32_t>(static_cast<std::uint32_t>(n));
    out_.insert(out_.end(), p, p + n);
  }
  void str(const std::string& s) { bytes(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()); }
  std::vector<std::uint8_t>& out() { return out_; }

 private:
  std::vector<std::uint8_t> out_;
};

class ByteReader {
 public:
  ByteReader(const std::uint8_t* p, std::size_t n, const std::string& what) : p_(p), n_(n), what_(what) {}
  template <typename T>
  T get(const char* field) {
    need(sizeof(T), field);
    const T v = internal::getLE<T>(p_ + at_);
    at_ += sizeof(T);
    return v;
  }
  double f64(const char* field) {
    need(8, field);
    const double v = internal::getDouble(p_ + at_);
    at_ += 8;
    return v;
  }
  /// A length-prefixed field: pointer into the message and its length.
  std::pair<const std::uint8_t*, std::size_t> bytes(const char* field) {
    const std::uint32_t n = get<std::uint32_t>(field);
    if (n > kMaxField) fail(std::string(field) + " claims " + std::to_string(n) + " bytes");
    need(static_cast<std::size_t>(n), field);
    const std::uint8_t* p = p_ + at_;
    at_ += static_cast<std::size_t>(n);
    return {p, static_cast<std::size_t>(n)};
  }
  std::string str(const char* field) {
    const auto [p, n] = bytes(field);
    return std::string(reinterpret_cast<const char*>(p), n);
  }
  std::size_t remaining() const { return n_ - at_; }
  [[noreturn]] void fail(const std::string& why) const {
    throw BlobFormatError("simulation outcome from " + what_ + ": " + why);
  }

 private:
  void need(std::size_t k, const char* field) const {
    if (k > n_ - at_) fail(std::string("truncated in ") + field);
  }
  const std::uint8_t* p_;
  std::size_t n_, at_ = 0;
  const std::string& what_;
};

}  // namespace

std::vector<std::uint8_t> encodeSimulationOutcome(const SimulationOutcome& o) {
  const SimulationResult& r = o.result;
  if (o.failure.empty() && r.positions.size() == 0)
    throw InvalidInputError("simulation outcome " + std::to_string(r.simulation_id) + ": succeeded without positions");
  ByteWriter w;
  w.out().insert(w.out().end(), kMagic, kMagic + 4);
  w.put<std::uint16_t>(kSimulationOutcomeVersion);
  w.put<std::uint16_t>(0);
  w.put<std::int64_t>(r.simulation_id);
  w.put<std::uint8_t>(r.rest_reached ? 1 : 0);
  for (double v : {r.sim_time_s, r.wall_time_s, r.render_time_s, r.hanging_depth_m}) w.f64(v);
  w.put<std::int64_t>(r.steps);
  w.put<std::int64_t>(r.rejected_steps);
  w.put<std::int32_t>(r.held_particle);
  w.str(r.projection);
  w.put<std::int32_t>(r.frame.width_px);
  w.put<std::int32_t>(r.frame.height_px);
  w.f64(r.frame.metres_per_pixel);
  w.f64(r.frame.top_margin_px);
  w.put<std::int32_t>(r.frame.supersample);
  w.f64(r.frame.coverage_threshold);
  const std::vector<std::uint8_t> positions =
      r.positions.size() == 0 ? std::vector<std::uint8_t>() : encodePositions(r.positions);
  w.bytes(positions.data(), positions.size());
  w.put<std::uint32_t>(static_cast<std::uint32_t>(r.views.size()));
  for (const ViewInput& v : r.views) {
    w.f64(v.view_angle_deg);
    const std::vector<std::uint8_t> mask = encodeMask(v.mask);
    w.bytes(mask.data(), mask.size());
  }
  w.str(o.failure);
  w.put<std::uint32_t>(crc32(w.out().data(), w.out().size()));
  return std::move(w.out());
}

SimulationOutcome decodeSimulationOutcome(const std::uint8_t* data, std::size_t size, const std::string& what) {
  const ByteReader in(data, data ? size : 0, what);
  if (!data || size < 8 + 4 || std::memcmp(data, kMagic, 4) != 0) in.fail("no THSO tag (not a simulation outcome)");
  const std::uint32_t stored = internal::getLE<std::uint32_t>(data + size - 4);
  if (crc32(data, size - 4) != stored) in.fail("CRC mismatch (damaged or truncated message)");
  ByteReader r(data, size - 4, what);
  r.get<std::uint32_t>("tag");
  const std::uint16_t version = r.get<std::uint16_t>("version");
  if (version != kSimulationOutcomeVersion) r.fail("unknown version " + std::to_string(version));
  r.get<std::uint16_t>("reserved");
  SimulationOutcome o;
  SimulationResult& s = o.result;
  s.simulation_id = r.get<std::int64_t>("simulation_id");
  s.rest_reached = r.get<std::uint8_t>("rest_reached") != 0;
  s.sim_time_s = r.f64("sim_time_s");
  s.wall_time_s = r.f64("wall_time_s");
  s.render_time_s = r.f64("render_time_s");
  s.hanging_depth_m = r.f64("hanging_depth_m");
  s.steps = static_cast<long>(r.get<std::int64_t>("steps"));
  s.rejected_steps = static_cast<long>(r.get<std::int64_t>("rejected_steps"));
  s.held_particle = r.get<std::int32_t>("held_particle");
  s.projection = r.str("projection");
  s.frame.width_px = r.get<std::int32_t>("width_px");
  s.frame.height_px = r.get<std::int32_t>("height_px");
  s.frame.metres_per_pixel = r.f64("metres_per_pixel");
  s.frame.top_margin_px = r.f64("top_margin_px");
  s.frame.supersample = r.get<std::int32_t>("supersample");
  s.frame.coverage_threshold = r.f64("coverage_threshold");
  const std::string row = what + " (simulation " + std::to_string(s.simulation_id) + ")";
  const auto [pos, pos_n] = r.bytes("positions");
  if (pos_n > 0) s.positions = decodePositions(pos, pos_n, row);
  const std::uint32_t views = r.get<std::uint32_t>("view count");
  if (views > kMaxViews) r.fail("claims " + std::to_string(views) + " views");
  s.views.reserve(static_cast<std::size_t>(views));
  for (std::uint32_t k = 0; k < views; ++k) {
    ViewInput v;
    v.view_angle_deg = r.f64("view angle");
    const auto [mask, mask_n] = r.bytes("mask");
    v.mask = decodeMask(mask, mask_n, row + " view " + std::to_string(k));
    s.views.push_back(std::move(v));
  }
  o.failure = r.str("failure");
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " bytes after the last field");
  return o;
}

}  // namespace db
}  // namespace textile_handling
