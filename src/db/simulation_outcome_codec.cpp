#include "textile_handling/db/simulation_outcome_codec.h"

#include <cstring>
#include <utility>

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
  void u(std::uint64_t v, int bytes) {
    for (int k = 0; k < bytes; ++k) out_.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
  }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    u(bits, 8);
  }
  void bytes(const std::uint8_t* p, std::size_t n) {
    u(n, 4);
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
  std::uint64_t u(int bytes, const char* field) {
    need(static_cast<std::size_t>(bytes), field);
    std::uint64_t v = 0;
    for (int k = 0; k < bytes; ++k) v |= static_cast<std::uint64_t>(p_[at_ + k]) << (8 * k);
    at_ += static_cast<std::size_t>(bytes);
    return v;
  }
  double f64(const char* field) {
    const std::uint64_t bits = u(8, field);
    double v;
    std::memcpy(&v, &bits, 8);
    return v;
  }
  /// A length-prefixed field: pointer into the message and its length.
  std::pair<const std::uint8_t*, std::size_t> bytes(const char* field) {
    const std::uint64_t n = u(4, field);
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
  w.u(kSimulationOutcomeVersion, 2);
  w.u(0, 2);
  w.u(static_cast<std::uint64_t>(r.simulation_id), 8);
  w.u(r.rest_reached ? 1 : 0, 1);
  for (double v : {r.sim_time_s, r.wall_time_s, r.render_time_s, r.hanging_depth_m}) w.f64(v);
  w.u(static_cast<std::uint64_t>(static_cast<std::int64_t>(r.steps)), 8);
  w.u(static_cast<std::uint64_t>(static_cast<std::int64_t>(r.rejected_steps)), 8);
  w.u(static_cast<std::uint32_t>(r.held_particle), 4);
  w.str(r.projection);
  w.u(static_cast<std::uint32_t>(r.frame.width_px), 4);
  w.u(static_cast<std::uint32_t>(r.frame.height_px), 4);
  w.f64(r.frame.metres_per_pixel);
  w.f64(r.frame.top_margin_px);
  w.u(static_cast<std::uint32_t>(r.frame.supersample), 4);
  w.f64(r.frame.coverage_threshold);
  const std::vector<std::uint8_t> positions =
      r.positions.size() == 0 ? std::vector<std::uint8_t>() : encodePositions(r.positions);
  w.bytes(positions.data(), positions.size());
  w.u(r.views.size(), 4);
  for (const ViewInput& v : r.views) {
    w.f64(v.view_angle_deg);
    const std::vector<std::uint8_t> mask = encodeMask(v.mask);
    w.bytes(mask.data(), mask.size());
  }
  w.str(o.failure);
  w.u(crc32(w.out().data(), w.out().size()), 4);
  return std::move(w.out());
}

SimulationOutcome decodeSimulationOutcome(const std::uint8_t* data, std::size_t size, const std::string& what) {
  const ByteReader in(data, data ? size : 0, what);
  if (!data || size < 8 + 4 || std::memcmp(data, kMagic, 4) != 0) in.fail("no THSO tag (not a simulation outcome)");
  const std::uint32_t stored = static_cast<std::uint32_t>(data[size - 4]) | static_cast<std::uint32_t>(data[size - 3]) << 8 |
                               static_cast<std::uint32_t>(data[size - 2]) << 16 |
                               static_cast<std::uint32_t>(data[size - 1]) << 24;
  if (crc32(data, size - 4) != stored) in.fail("CRC mismatch (damaged or truncated message)");
  ByteReader r(data, size - 4, what);
  r.u(4, "tag");
  const std::uint64_t version = r.u(2, "version");
  if (version != kSimulationOutcomeVersion) r.fail("unknown version " + std::to_string(version));
  r.u(2, "reserved");
  SimulationOutcome o;
  SimulationResult& s = o.result;
  s.simulation_id = static_cast<std::int64_t>(r.u(8, "simulation_id"));
  s.rest_reached = r.u(1, "rest_reached") != 0;
  s.sim_time_s = r.f64("sim_time_s");
  s.wall_time_s = r.f64("wall_time_s");
  s.render_time_s = r.f64("render_time_s");
  s.hanging_depth_m = r.f64("hanging_depth_m");
  s.steps = static_cast<long>(static_cast<std::int64_t>(r.u(8, "steps")));
  s.rejected_steps = static_cast<long>(static_cast<std::int64_t>(r.u(8, "rejected_steps")));
  s.held_particle = static_cast<int>(static_cast<std::int32_t>(r.u(4, "held_particle")));
  s.projection = r.str("projection");
  s.frame.width_px = static_cast<int>(static_cast<std::int32_t>(r.u(4, "width_px")));
  s.frame.height_px = static_cast<int>(static_cast<std::int32_t>(r.u(4, "height_px")));
  s.frame.metres_per_pixel = r.f64("metres_per_pixel");
  s.frame.top_margin_px = r.f64("top_margin_px");
  s.frame.supersample = static_cast<int>(static_cast<std::int32_t>(r.u(4, "supersample")));
  s.frame.coverage_threshold = r.f64("coverage_threshold");
  const std::string row = what + " (simulation " + std::to_string(s.simulation_id) + ")";
  const auto [pos, pos_n] = r.bytes("positions");
  if (pos_n > 0) s.positions = decodePositions(pos, pos_n, row);
  const std::uint64_t views = r.u(4, "view count");
  if (views > kMaxViews) r.fail("claims " + std::to_string(views) + " views");
  s.views.reserve(static_cast<std::size_t>(views));
  for (std::uint64_t k = 0; k < views; ++k) {
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
