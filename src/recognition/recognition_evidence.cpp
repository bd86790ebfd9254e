#include "textile_handling/recognition/recognition_evidence.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

void EvidenceOptions::validate() const {
  auto unit = [](double v) { return v >= 0 && v <= 1; };
  if (!unit(min_score)) throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.min_score must be in [0, 1]");
  if (!unit(min_coverage))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.min_coverage must be in [0, 1]");
  if (!unit(max_colour_fraction))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.max_colour_fraction must be in [0, 1]");
  if (!unit(max_lost_view_fraction))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.max_lost_view_fraction must be in [0, 1]");
  if (!unit(contradiction_gap))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.contradiction_gap must be in [0, 1]");
  if (!unit(contradiction_regret))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "evidence.contradiction_regret must be in [0, 1]");
}

std::vector<bool> contradictingImages(const std::vector<double>& coverage, const std::vector<double>& regret,
                                      const EvidenceOptions& o) {
  std::vector<bool> out(coverage.size(), false);
  if (coverage.size() < 2) return out;
  const double best = *std::max_element(coverage.begin(), coverage.end());
  const bool with_regret = regret.size() == coverage.size();
  const std::size_t least = with_regret ? static_cast<std::size_t>(std::min_element(regret.begin(), regret.end()) - regret.begin()) : 0;
  for (std::size_t i = 0; i < coverage.size(); ++i)
    out[i] = coverage[i] < best - o.contradiction_gap || (with_regret && i != least && regret[i] > o.contradiction_regret);
  return out;
}

std::string completenessProblem(const TextileCompleteness& c, const EvidenceOptions& o) {
  const std::string name = "textile '" + c.textile + "'";
  if (c.unbuilt()) return name + " has no finished simulations yet (still building?), so it cannot be ruled out";
  if (c.loaded_views == 0)
    return name + " has no usable stored views: the " + std::to_string(c.stored.expected_views) + " views of its " +
           std::to_string(c.stored.done_simulations) + " finished simulations are damaged or missing";
  const double lost_views =
      c.stored.expected_views > 0
          ? static_cast<double>(std::max<std::int64_t>(0, c.stored.expected_views - c.loaded_views)) /
                static_cast<double>(c.stored.expected_views)
          : 0.0;
  const double lost_sims =
      static_cast<double>(std::max<std::int64_t>(0, c.stored.done_simulations - c.loaded_hold_points)) /
      static_cast<double>(c.stored.done_simulations);
  if (lost_views <= o.max_lost_view_fraction && lost_sims <= o.max_lost_view_fraction) return "";
  std::ostringstream os;
  os << name << " lost stored entries: " << c.loaded_views << " of " << c.stored.expected_views << " views ("
     << c.damaged_views << " damaged) and " << c.loaded_hold_points << " of " << c.stored.done_simulations
     << " finished simulations loaded (tolerance " << 100 * o.max_lost_view_fraction << " %)";
  return os.str();
}

void addCompleteness(const db::DrapeMatchIndex& index, TextileCompleteness* c, std::vector<db::SkippedView>* skipped) {
  c->loaded_views += static_cast<std::int64_t>(index.loadedViews(c->textile));
  std::set<std::int64_t> sims;
  for (const auto& h : index.hold_points)
    if (h.textile == c->textile) sims.insert(h.simulation_id);
  c->loaded_hold_points += static_cast<std::int64_t>(sims.size());
  for (const auto& v : index.skipped_views)
    if (v.textile == c->textile) {
      ++c->damaged_views;
      skipped->push_back(v);
    }
}

void noteCompleteness(const TextileCompleteness& c, const EvidenceOptions& o, std::vector<std::string>* problems,
                      std::vector<std::string>* warnings) {
  const std::string problem = completenessProblem(c, o);
  if (problem.empty()) return;
  if (c.unbuilt() && o.ignore_unbuilt_textiles)
    warnings->push_back(problem + " (ignored: ignore_unbuilt_textiles)");
  else
    problems->push_back(problem);
}

std::vector<std::string> skippedViewLines(const std::vector<db::SkippedView>& skipped) {
  std::map<std::string, std::vector<const db::SkippedView*>> by_textile;
  for (const auto& s : skipped) by_textile[s.textile].push_back(&s);
  std::vector<std::string> out;
  constexpr std::size_t kListed = 5;  // a log line, not a dump
  for (const auto& [textile, views] : by_textile) {
    std::ostringstream os;
    os << "textile '" << textile << "': " << views.size() << " damaged stored view(s) skipped:";
    for (std::size_t k = 0; k < views.size() && k < kListed; ++k)
      os << " view " << views[k]->view_id << " (simulation " << views[k]->simulation_id << ")";
    if (views.size() > kListed) os << " ...";
    os << "; " << views.front()->reason;
    out.push_back(os.str());
  }
  return out;
}

double silhouetteCoverage(const vision::BitMask& query, const vision::BitMask& matched, int max_shift) {
  const std::int64_t q = query.count(), m = matched.count();
  if (q == 0 || m == 0 || !query.sameSize(matched)) return 0.0;
  const vision::ShiftedIou best = vision::bestShiftIou(query, matched, max_shift, max_shift);
  const double inter = static_cast<double>(vision::andCount(query, matched, best.dx, best.dy));
  return std::min(inter / static_cast<double>(q), inter / static_cast<double>(m));
}

void checkEvidence(double score, double coverage, const EvidenceOptions& o) {
  if (score >= o.min_score && coverage >= o.min_coverage) return;
  std::ostringstream os;
  os.precision(3);
  os << "the best match is too weak to report: silhouette score " << score << " (floor " << o.min_score
     << "), coverage " << coverage << " (floor " << o.min_coverage
     << "); is a textile held in front of the expected background?";
  throw RecognitionError(RecognitionErrorCode::kInsufficientEvidence, os.str());
}

void checkColourFraction(double colour_fraction, const EvidenceOptions& o) {
  if (!(colour_fraction > o.max_colour_fraction)) return;
  std::ostringstream os;
  os.precision(3);
  os << "the colour model marks " << 100 * colour_fraction << " % of the image as textile (ceiling "
     << 100 * o.max_colour_fraction
     << " %): the frame does not show the expected background (dark or overexposed frame, covered lens, "
        "other backdrop?)";
  throw RecognitionError(RecognitionErrorCode::kInsufficientEvidence, os.str());
}

void checkPixelLimit(std::int64_t width, std::int64_t height, std::int64_t max_pixels, const std::string& what) {
  if (width <= 0 || height <= 0) return;  // empty images are the caller's kInvalidImage
  if (width > max_pixels / height)
    throw RecognitionError(RecognitionErrorCode::kImageTooLarge,
                           what + " is " + std::to_string(width) + " x " + std::to_string(height) + " px, more than the " +
                               std::to_string(max_pixels) + " pixel limit (max_image_pixels)");
}

}  // namespace recognition
}  // namespace textile_handling
