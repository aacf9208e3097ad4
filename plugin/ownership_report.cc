// The ownership report's HTML page (see ownership_report.h).
#include "plugin/ownership_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "gaussian/util/error.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

// printf into a string.
template <typename... Args>
std::string Printf(const char* format, Args... args) {
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), format, args...);
  return buffer;
}

// Height (chart units of 260) of a bar of 0 bits wrong: a sliver, so that a
// view read all right still shows.
constexpr double kZeroBarHeight = 3;

// A shell command as <pre> text whose options ("--downscale") never wrap
// inside: the browser breaks lines after a hyphen. The text copies as is.
std::string CommandHtml(const std::string& command) {
  std::string html;
  size_t start = 0;
  while (start < command.size()) {
    const size_t space = command.find(' ', start);
    const size_t end = space == std::string::npos ? command.size() : space;
    const std::string word = command.substr(start, end - start);
    html += word.rfind("--", 0) == 0
                ? "<span class=\"opt\">" + HtmlEscape(word) + "</span>"
                : HtmlEscape(word);
    if (space == std::string::npos) break;
    html += ' ';
    start = space + 1;
  }
  return html;
}

// A metric for a table: "inf" for identical images, "n/a" when not computed.
std::string Metric(const char* format, double value) {
  if (!std::isfinite(value)) return std::isinf(value) ? "inf" : "n/a";
  return Printf(format, value);
}

// 3.5e-15 as "3.5 × 10<sup>−15</sup>" (HTML), plain below 1e-3 only.
std::string Scientific(double value) {
  if (value >= 1e-3 || value <= 0) return Printf("%.3g", value);
  const int exponent = int(std::floor(std::log10(value)));
  double mantissa = value / std::pow(10.0, exponent);
  std::string m = Printf("%.2g", mantissa);
  if (m == "1") return "10<sup>&minus;" + std::to_string(-exponent) + "</sup>";
  return m + " &times; 10<sup>&minus;" + std::to_string(-exponent) + "</sup>";
}

// A probability in words: "55.7%", "1 in 1,000,000", "1 in 2.8 × 10<sup>14
// </sup>".
std::string Chance(double p) {
  if (p >= 1e-3) return Printf("%.3g%%", 100 * p);
  const double x = 1 / p;
  if (x < 1e9) {
    std::string digits = Printf("%.0f", x);
    for (int k = int(digits.size()) - 3; k > 0; k -= 3) {
      digits.insert(size_t(k), ",");
    }
    return "1 in " + digits;
  }
  const int exponent = int(std::floor(std::log10(x)));
  return "1 in " + Printf("%.2g", x / std::pow(10.0, exponent)) +
         " &times; 10<sup>" + std::to_string(exponent) + "</sup>";
}

// The claim in the other reading (empty when it was not read so).
std::string OtherReadingRow(const ExtractionResult& other,
                            bool other_is_owner) {
  if (other.views.empty()) return "";
  return std::string("<tr><th>") +
         (other_is_owner ? "Read as the owner" : "Read blind") +
         "</th><td>one view alone: bit error rate mean " +
         Printf("%.2f", 100 * other.mean_view_ber) + "%, 90th percentile " +
         Printf("%.2f", 100 * other.p90_view_ber) +
         "%; all views: " + std::to_string(other.bit_errors) + " bits wrong, " +
         HtmlEscape(ToString(other.verdict)) + "<br><span class=\"small\">" +
         (other_is_owner
              ? "each bit from the difference of the decoder's outputs on the "
                "watermarked and the raw model's renders of the same view"
              : "each bit from the decoder's outputs on the watermarked "
                "model's renders alone (no raw model)") +
         "</span></td></tr>\n";
}

// How the claim was read, for its card.
std::string ReadingNote(bool owner_reading) {
  return owner_reading
             ? "<p class=\"small\">Read as the owner: each bit from the "
               "difference between the decoder's outputs on the watermarked "
               "and on the raw model's render of the same view (the owner "
               "keeps the raw model; the embedding optimised this "
               "reading).</p>\n"
             : "<p class=\"small\">Read blind: each bit from the decoder's "
               "outputs on the watermarked model's renders alone.</p>\n";
}

// CSS class of a verdict.
const char* VerdictClass(Verdict verdict) {
  switch (verdict) {
    case Verdict::kPresent:
      return "present";
    case Verdict::kAbsent:
      return "absent";
    case Verdict::kInconclusive:
      return "inconclusive";
  }
  return "inconclusive";
}

std::string Hex(uint64_t value) {
  return Printf("%llx", static_cast<unsigned long long>(value));
}

// "1.2 MB" for a byte count.
std::string Size(uint64_t bytes) {
  if (bytes < 10000) return std::to_string(bytes) + " bytes";
  if (bytes < 10000000) return Printf("%.1f kB", bytes / 1e3);
  return Printf("%.1f MB", bytes / 1e6);
}

std::string ImgTag(const ImageRGB& image, const std::string& id,
                   const std::string& alt) {
  // Shown at its stored size up to a column's width; pixelated so that an
  // upscaled small render shows its pixels rather than a blur.
  const int shown = std::min(image.width, 360);
  return "<img id=\"" + id + "\" alt=\"" + HtmlEscape(alt) + "\" width=\"" +
         std::to_string(shown) + "\" height=\"" +
         std::to_string(int(std::lround(double(shown) * image.height /
                                        std::max(1, image.width)))) +
         "\" src=\"data:image/png;base64," + Base64(EncodePng(image)) + "\">";
}

// The claim's key: its fingerprint, or why an unkeyed claim must have been
// fixed before the suspect was read.
std::string KeyRow(const std::string& fingerprint) {
  if (fingerprint.empty()) {
    return "<tr><th>Owner's key</th><td>none: the bits claimed are the "
           "message as typed. The false-positive rate below holds only for a "
           "claim fixed before the model was read; a claim chosen after "
           "reading it (such as the message read from it) has "
           "none.</td></tr>\n";
  }
  return "<tr><th>Owner's key</th><td>SHA-256 <code>" + fingerprint +
         "</code>: the bits claimed are the message XOR a stream drawn from "
         "the key, a random pattern fixed when the key was drawn (compare the "
         "fingerprint with the one registered at embedding)</td></tr>\n";
}

// The claimed bits with the ones read wrong marked.
std::string BitRow(const Bits& read, const Bits& expected) {
  std::string out = "<span class=\"bits\">";
  for (size_t i = 0; i < read.size(); ++i) {
    const bool wrong = i < expected.size() && read[i] != expected[i];
    if (i > 0 && i % 8 == 0) out += " ";
    out += wrong ? "<b class=\"wrong\">" : "<b>";
    out += read[i] ? '1' : '0';
    out += "</b>";
  }
  return out + "</span>";
}

// Per-view BER of the watermarked and the raw model as an SVG bar chart,
// with the chance level and the BER at which one view alone would pass.
std::string BerChart(const OwnershipReport& r) {
  const std::vector<ViewDecode>& wm = r.claim.views;
  const std::vector<ViewDecode>& raw = r.raw.views;
  const size_t n = wm.size();
  const int bits = int(r.claim.recovered.size());
  if (n == 0 || bits == 0) return "";
  const double width = 1000, height = 260, left = 48, right = 12, top = 16;
  const double bottom = n <= 16 ? 70 : 40;
  const double plot_w = width - left - right, plot_h = height - top - bottom;
  const auto ber = [&](const ViewDecode& v) {
    return std::max(0, v.bit_errors) / double(bits);
  };
  double y_max = 0.6;
  for (size_t k = 0; k < n; ++k) {
    y_max = std::max(y_max, ber(wm[k]));
    if (k < raw.size()) y_max = std::max(y_max, ber(raw[k]));
  }
  y_max = std::min(1.0, std::ceil(y_max * 10 - 1e-9) / 10);
  const auto y = [&](double v) { return top + plot_h * (1 - v / y_max); };
  std::ostringstream s;
  s << "<svg id=\"ber-chart\" viewBox=\"0 0 " << width << " " << height
    << "\" width=\"100%\" role=\"img\" aria-label=\"bit error rate per "
       "view\">\n";
  for (int t = 0; t <= int(std::lround(y_max * 10)); ++t) {
    const double v = t / 10.0;
    s << Printf(
        "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" "
        "class=\"grid\"/><text x=\"%.1f\" y=\"%.1f\" class=\"axis\" "
        "text-anchor=\"end\">%d%%</text>\n",
        left, width - right, y(v), y(v), left - 6, y(v) + 4, t * 10);
  }
  const double group = plot_w / n;
  const double bar = std::min(18.0, group * 0.4);
  for (size_t k = 0; k < n; ++k) {
    const double x0 = left + group * k + group / 2 - bar;
    const double v = ber(wm[k]);
    // A view that reads every bit right stays visible: a sliver at the axis.
    const double wm_height = std::max(y(0) - y(v), kZeroBarHeight);
    s << Printf(
        "<rect class=\"wm\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" "
        "height=\"%.1f\"><title>",
        x0, y(0) - wm_height, bar, wm_height);
    s << HtmlEscape(wm[k].name) << ": watermarked " << wm[k].bit_errors
      << " of " << bits << " bits wrong</title></rect>\n";
    if (k < raw.size()) {
      const double u = ber(raw[k]);
      const double raw_height = std::max(y(0) - y(u), kZeroBarHeight);
      s << Printf(
          "<rect class=\"raw\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" "
          "height=\"%.1f\"><title>",
          x0 + bar, y(0) - raw_height, bar, raw_height);
      s << HtmlEscape(raw[k].name) << ": raw " << raw[k].bit_errors << " of "
        << bits << " bits wrong</title></rect>\n";
    }
    const double xc = left + group * (k + 0.5);
    if (n <= 16) {
      s << Printf(
          "<text class=\"axis\" text-anchor=\"end\" "
          "transform=\"translate(%.1f %.1f) rotate(-35)\">",
          xc + 4, y(0) + 14);
      s << HtmlEscape(wm[k].name) << "</text>\n";
    } else if (k % size_t(std::ceil(n / 24.0)) == 0) {
      s << Printf(
          "<text class=\"axis\" x=\"%.1f\" y=\"%.1f\" "
          "text-anchor=\"middle\">%zu</text>\n",
          xc, y(0) + 16, k + 1);
    }
  }
  // Reference lines; their legend is under the chart, clear of the bars.
  s << Printf(
      "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" "
      "class=\"chance\"/>\n",
      left, width - right, y(0.5), y(0.5));
  const int k_max = MaxErrorsForPresence(bits, r.claim.thresholds.present_p);
  if (k_max >= 0) {
    const double v = (k_max + 0.5) / bits;
    s << Printf(
        "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" "
        "class=\"threshold\"/>\n",
        left, width - right, y(v), y(v));
  }
  s << Printf(
      "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" "
      "class=\"axisline\"/>\n",
      left, width - right, y(0), y(0));
  if (n > 16) {
    s << Printf(
        "<text class=\"axis\" x=\"%.1f\" y=\"%.1f\" "
        "text-anchor=\"middle\">view number</text>\n",
        left + plot_w / 2, height - 6);
  }
  s << "</svg>\n<p class=\"legend small\"><span style=\"background:#3465d9\">"
       "</span>watermarked<span style=\"background:#b3b9c5\"></span>raw"
       "<span class=\"line chance\"></span>chance level, 50% (what an "
       "unmarked model reads)";
  if (k_max >= 0) {
    s << "<span class=\"line threshold\"></span>below this line one view "
         "alone would read &lsquo;present&rsquo; (at most "
      << k_max << " of " << bits << " bits wrong)";
  }
  s << "</p>\n";
  return s.str();
}

std::string QualityRow(const QualityComparison& c, bool lpips) {
  const QualityMetrics& m = c.mean;
  std::string row = "<tr><td>" + HtmlEscape(c.label) + "</td><td>" +
                    Metric("%.2f", m.psnr) + "</td><td>" +
                    Metric("%.4f", m.ssim) + "</td><td>" +
                    Metric("%.4f", m.ms_ssim) + "</td>";
  if (lpips) {
    row += "<td>" + (m.has_lpips ? Metric("%.4f", m.lpips) : "") + "</td>";
  }
  return row + "</tr>\n";
}

const char* kStyle = R"css(
body { font: 15px/1.45 "DejaVu Sans", Arial, sans-serif; color: #1d2330;
  background: #f3f4f7; margin: 0; }
main { max-width: 1100px; margin: 0 auto; padding: 20px 24px 40px; }
h1 { font-size: 26px; margin: 8px 0 2px; }
h2 { font-size: 19px; margin: 28px 0 8px; border-bottom: 1px solid #cdd2dc;
  padding-bottom: 3px; }
.sub { color: #5a6272; margin: 0 0 14px; }
section.card { background: #fff; border: 1px solid #dde1e8; border-radius: 6px;
  padding: 14px 18px; margin: 12px 0; }
.claim { border-left: 10px solid #888; }
.claim.present { border-left-color: #1e8a44; }
.claim.absent { border-left-color: #c0392b; }
.claim.inconclusive { border-left-color: #d68910; }
.verdict { font-size: 28px; font-weight: bold; text-transform: uppercase;
  letter-spacing: 0.5px; }
.present .verdict, td.present { color: #1e8a44; }
.absent .verdict, td.absent { color: #c0392b; }
.inconclusive .verdict, td.inconclusive { color: #b9770e; }
tr.control td.absent { color: #5a6272; }
table { border-collapse: collapse; width: 100%; }
th, td { text-align: left; padding: 4px 8px; border-bottom: 1px solid #e6e8ee;
  vertical-align: top; }
th { background: #eef0f4; font-weight: 600; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
table.facts th { width: 210px; background: none; }
.bits { font-family: "DejaVu Sans Mono", monospace; font-size: 13px;
  word-break: break-all; }
.bits b { font-weight: normal; }
.bits b.wrong { background: #f5b7b1; color: #7b241c; font-weight: bold; }
.mono, code, pre { font-family: "DejaVu Sans Mono", monospace; font-size: 13px; }
pre { background: #1f2430; color: #e8eaf0; padding: 10px 12px; border-radius: 4px;
  white-space: pre-wrap; overflow-wrap: anywhere; margin: 4px 0 12px; }
pre .opt { white-space: nowrap; }
th, td.num, td.nowrap { white-space: nowrap; }
.wide { overflow-x: auto; }
#attacks { font-size: 13.5px; }
#attacks th { white-space: normal; }
#attacks td.attack { overflow-wrap: anywhere; min-width: 9em; }
.views { display: grid; grid-template-columns: repeat(3, minmax(0, 1fr));
  gap: 10px 14px; align-items: start; }
.views figure { margin: 0; }
.views img { display: block; max-width: 100%; height: auto;
  image-rendering: pixelated; background: #000; border: 1px solid #c9ced8; }
.views figcaption { font-size: 13px; color: #3b4252; margin-top: 3px; }
.viewname { grid-column: 1 / -1; font-weight: 600; margin-top: 6px; }
.bar { display: inline-block; height: 10px; background: #5b8def;
  vertical-align: middle; margin-right: 6px; }
.barbox { display: inline-block; width: 60px; background: #e6e9f0;
  vertical-align: middle; margin-right: 6px; }
.barbox .bar { margin: 0; }
svg .grid { stroke: #e3e6ec; } svg .axisline { stroke: #5a6272; }
svg .axis { font-size: 12px; fill: #5a6272; }
svg .note { font-size: 12px; fill: #3b4252; }
svg .wm { fill: #3465d9; } svg .raw { fill: #b3b9c5; }
svg .chance { stroke: #8a919e; stroke-dasharray: 6 4; }
svg .threshold { stroke: #1e8a44; stroke-dasharray: 3 3; }
.legend { margin-top: 0; }
.legend span { display: inline-block; width: 12px; height: 12px;
  vertical-align: -1px; margin: 0 5px 0 16px; }
.legend span:first-child { margin-left: 0; }
.legend span.line { width: 26px; height: 0; vertical-align: 4px; }
.legend span.chance { border-top: 2px dashed #8a919e; }
.legend span.threshold { border-top: 2px dashed #1e8a44; }
.small { font-size: 13px; color: #5a6272; }
sup { line-height: 0; font-size: 0.75em; }
details summary { cursor: pointer; color: #2c4f9e; margin: 6px 0; }
)css";

}  // namespace

std::string HtmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t left = std::min<size_t>(3, bytes.size() - i);
    uint32_t word = uint32_t(uint8_t(bytes[i])) << 16;
    if (left > 1) word |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    if (left > 2) word |= uint32_t(uint8_t(bytes[i + 2]));
    out += kAlphabet[(word >> 18) & 63];
    out += kAlphabet[(word >> 12) & 63];
    out += left > 1 ? kAlphabet[(word >> 6) & 63] : '=';
    out += left > 2 ? kAlphabet[word & 63] : '=';
  }
  return out;
}

std::string EncodePng(const ImageRGB& image) {
  if (image.width <= 0 || image.height <= 0) Fail("report: empty image");
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const float* p = image.At(x, y);
      cv::Vec3b& q = bgr.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        q[2 - c] = uint8_t(std::lround(255 * std::clamp(p[c], 0.f, 1.f)));
      }
    }
  }
  std::vector<uchar> buffer;
  if (!cv::imencode(".png", bgr, buffer, {cv::IMWRITE_PNG_COMPRESSION, 9})) {
    Fail("report: PNG encoding failed");
  }
  return std::string(buffer.begin(), buffer.end());
}

std::string OwnershipReportToHtml(const OwnershipReport& r) {
  const ExtractionResult& claim = r.claim;
  const EvaluationReport& ev = r.evaluation;
  const int bits = int(claim.recovered.size());
  const double fpr = claim.thresholds.present_p;
  const int k_max = MaxErrorsForPresence(bits, fpr);
  const std::string verdict = ToString(claim.verdict);
  const char* verdict_class = VerdictClass(claim.verdict);
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
    << "<meta name=\"viewport\" content=\"width=device-width, "
       "initial-scale=1\">\n"
    << "<title>Ownership report: " << HtmlEscape(verdict) << " ("
    << HtmlEscape(r.message_text) << ")</title>\n<style>" << kStyle
    << "</style>\n</head>\n<body>\n<main>\n";
  h << "<h1>Watermark ownership report</h1>\n<p class=\"sub\">WATER-GS "
       "watermark of a 3D Gaussian Splatting model, checked by "
    << HtmlEscape(r.generator) << " on " << ev.view_names.size()
    << (ev.view_names.size() == 1 ? " view" : " views");
  if (r.workspace_views > ev.view_names.size()) {
    h << " (of " << r.workspace_views << " cameras)";
  }
  h << " of " << HtmlEscape(r.workspace_path) << ".</p>\n";

  // The claim.
  h << "<section class=\"card claim " << verdict_class << "\" id=\"claim\">\n"
    << "<div class=\"verdict\">" << HtmlEscape(verdict) << "</div>\n<p>The "
    << "model <code>" << HtmlEscape(r.watermarked_path)
    << "</code> was rendered from " << ev.view_names.size() << " camera"
    << (ev.view_names.size() == 1 ? "" : "s") << " and the decoder read a "
    << bits << "-bit message from the renders. "
    << "It differs from the claimed message in <b>" << claim.bit_errors
    << " of " << bits << "</b> bits.</p>\n"
    << ReadingNote(r.owner_reading) << "<table class=\"facts\">\n"
    << "<tr><th>Claimed message</th><td><code>" << HtmlEscape(r.message_text)
    << "</code> = hex <code>" << BitsToHex(claim.expected)
    << "</code></td></tr>\n"
    << KeyRow(r.key_fingerprint) << "<tr><th>Read from the model</th><td>"
    << BitRow(claim.recovered, claim.expected)
    << "<br><span class=\"small\">bits read wrong are marked red</span>"
    << "</td></tr>\n"
    << "<tr><th>Bit errors</th><td>" << claim.bit_errors << " of " << bits
    << " (bit error rate " << Printf("%.2f", 100 * claim.ber)
    << "%, from the mean of all views' decoder outputs)</td></tr>\n"
    << "<tr><th>One view alone</th><td>bit error rate mean "
    << Printf("%.2f", 100 * claim.mean_view_ber) << "%, median "
    << Printf("%.2f", 100 * claim.median_view_ber) << "%, 90th percentile "
    << Printf("%.2f", 100 * claim.p90_view_ber) << "% over the "
    << claim.views.size()
    << " views, each decoded on its own (what a single screenshot of the "
       "scene reads)</td></tr>\n"
    << OtherReadingRow(r.claim_other, !r.owner_reading)
    << "<tr><th>p-value</th><td><b>" << Scientific(claim.p_value)
    << "</b>: if this model carried no watermark, each bit would match the "
       "claimed message only by chance, like a coin toss; the chance of "
    << bits - claim.bit_errors << " or more of " << bits
    << " matching that way is " << Chance(claim.p_value) << ".</td></tr>\n"
    << "<tr><th>False-positive rate</th><td><b>" << Scientific(fpr)
    << "</b>: the watermark is declared present only when p &le; "
    << Scientific(fpr);
  if (k_max >= 0) {
    h << " (at most " << k_max << " of " << bits << " bits wrong)";
  }
  h << (r.key_fingerprint.empty()
            ? ", so a model without this watermark is wrongly declared to "
              "carry it with a chance of at most "
            : ", so, over the owner's choice of key, a model without this "
              "watermark is wrongly declared to carry it with a chance of at "
              "most ")
    << Chance(fpr)
    << (r.key_fingerprint.empty()
            ? ", provided the claim was fixed before the model was read "
              "(without a key, measured on unmarked scenes, a fixed message "
              "can pass more often: docs/verification.md)"
            : "")
    << ". Above p = " << Scientific(claim.thresholds.absent_p)
    << " the verdict is &lsquo;absent&rsquo;, in between "
       "&lsquo;inconclusive&rsquo;.</td></tr>\n"
    << "<tr><th>Decoder</th><td><code>" << HtmlEscape(r.decoder.path)
    << "</code>, " << Size(r.decoder.bytes) << ", FNV-1a <code>"
    << Hex(r.decoder.fnv1a) << "</code></td></tr>\n";
  if (!r.raw.recovered.empty()) {
    h << "<tr><th>Control: the raw model</th><td>" << r.raw.bit_errors << " of "
      << bits << " bits wrong, p = " << Scientific(r.raw.p_value)
      << ": <span class=\"" << VerdictClass(r.raw.verdict) << "\">"
      << HtmlEscape(ToString(r.raw.verdict))
      << "</span> (the same model before the watermark, read the same "
         "way)</td></tr>\n";
  }
  h << "</table>\n</section>\n";

  // The views.
  if (!r.shown.empty()) {
    h << "<h2>What the watermark changes</h2>\n<p class=\"small\">Each row: "
         "the raw model's render, the watermarked model's render from the "
         "same camera, and their absolute difference amplified "
      << kReportDifferenceGain
      << "&times; (black = identical). PSNR and SSIM compare the "
         "watermarked render with the raw one.</p>\n<div class=\"views\">\n";
    for (size_t k = 0; k < r.shown.size(); ++k) {
      const ReportView& v = r.shown[k];
      const std::string id = std::to_string(k);
      std::string size = std::to_string(v.render_width) + "&times;" +
                         std::to_string(v.render_height);
      if (v.raw.width != v.render_width) {
        size += " (shown at " + std::to_string(v.raw.width) + "&times;" +
                std::to_string(v.raw.height) + ")";
      }
      h << "<div class=\"viewname\">View " << HtmlEscape(v.name) << " &mdash; "
        << size << ", PSNR " << Metric("%.2f", v.psnr) << " dB, SSIM "
        << Metric("%.4f", v.ssim) << ", this view alone: " << v.bit_errors
        << " of " << bits << " bits wrong</div>\n"
        << "<figure>" << ImgTag(v.raw, "raw-" + id, "raw render of " + v.name)
        << "<figcaption>raw model</figcaption></figure>\n"
        << "<figure>"
        << ImgTag(v.watermarked, "wm-" + id, "watermarked render of " + v.name)
        << "<figcaption>watermarked model</figcaption></figure>\n"
        << "<figure>"
        << ImgTag(v.difference, "diff-" + id, "difference of " + v.name)
        << "<figcaption>|watermarked &minus; raw| &times; "
        << kReportDifferenceGain << "</figcaption></figure>\n";
    }
    h << "</div>\n";
  }

  // BER per view.
  h << "<h2>Bit error rate per view</h2>\n<p class=\"small\">Each camera "
       "read alone, the watermarked and the raw model side by side. The "
       "verdict above reads the mean of all views' decoder outputs (BER "
    << Printf("%.2f", 100 * claim.ber)
    << "%), which is more reliable than any single view.</p>\n"
    << BerChart(r);

  // Image quality.
  const bool lpips = ev.vs_raw.mean.has_lpips;
  h << "<h2>Image quality (mean over " << ev.view_names.size()
    << (ev.view_names.size() == 1 ? " view" : " views") << ")</h2>\n"
    << "<table id=\"quality\"><tr><th>Comparison</th><th class=\"num\">PSNR "
       "(dB)</th><th class=\"num\">SSIM</th><th class=\"num\">MS-SSIM</th>"
    << (lpips ? "<th class=\"num\">LPIPS (VGG)</th>" : "") << "</tr>\n";
  for (const QualityComparison* c :
       {&ev.vs_raw, &ev.vs_ground_truth, &ev.raw_vs_ground_truth}) {
    std::string row = QualityRow(*c, lpips);
    // Numbers right-aligned: every cell after the first.
    size_t at = row.find("</td><td>");
    while (at != std::string::npos) {
      row.replace(at, 9, "</td><td class=\"num\">");
      at = row.find("</td><td>", at + 10);
    }
    h << row;
  }
  h << "</table>\n";
  if (!ev.ground_truth_note.empty()) {
    h << "<p class=\"small\">Ground truth: " << HtmlEscape(ev.ground_truth_note)
      << ".</p>\n";
  }
  if (!ev.lpips_note.empty()) {
    h << "<p class=\"small\">LPIPS: " << HtmlEscape(ev.lpips_note) << ".</p>\n";
  }

  // Attacks.
  h << "<h2>Attacks</h2>\n<p class=\"small\">The watermarked model attacked "
       "in 3D (the file changed) or in 2D (its renders changed before "
       "decoding), each alone, read on the same views; then the raw model "
       "(the control, which should read &lsquo;absent&rsquo;) and any "
       "suspect copies given.</p>\n<div class=\"wide\"><table id=\"attacks\">"
       "<tr><th>Model</th><th>Attack</th><th class=\"num\">Gaussians</th>"
       "<th class=\"num\">PSNR vs truth</th><th>Bit error rate (bits "
       "wrong)</th><th class=\"num\">p-value</th><th>Verdict</th><th "
       "class=\"num\">One view: BER mean / p90</th></tr>\n";
  for (const RobustnessRow& row : ev.robustness) {
    // The raw model read against itself is all ties: its control is blind.
    const bool owner_first =
        r.owner_reading && row.model != "raw" && !row.owner.views.empty();
    const ExtractionResult& e = owner_first ? row.owner : row.extraction;
    const ExtractionResult& other = owner_first ? row.extraction : row.owner;
    std::string model = row.model, attack = row.attack;
    if (row.kind == "3d") attack += " (3D)";
    if (row.kind == "2d") attack += " (2D, renders)";
    if (row.model == "raw") model = "raw (control)";
    if (row.model == "file") {
      model = "suspect copy";
      attack = "<code>" + HtmlEscape(row.attack) + "</code>";
    } else {
      attack = HtmlEscape(attack);
    }
    h << "<tr" << (row.model == "raw" ? " class=\"control\"" : "") << "><td>"
      << HtmlEscape(model) << "</td><td class=\"attack\">" << attack
      << "</td><td class=\"num\">" << row.num_gaussians
      << "</td><td class=\"num\">"
      << (std::isfinite(row.psnr) ? Printf("%.2f", row.psnr) + " dB"
                                  : std::string("n/a"))
      << "</td><td class=\"nowrap\"><span "
      << "class=\"barbox\"><span "
      << "class=\"bar\" style=\"width:" << Printf("%.0f", 100 * e.ber)
      << "%\"></span></span>" << Printf("%.2f", 100 * e.ber) << "% ("
      << e.bit_errors << " / " << bits << ")</td><td class=\"num\">"
      << Scientific(e.p_value) << "</td><td class=\"" << VerdictClass(e.verdict)
      << "\">" << HtmlEscape(ToString(e.verdict)) << "</td><td class=\"num\">"
      << Printf("%.1f", 100 * e.mean_view_ber) << "% / "
      << Printf("%.1f", 100 * e.p90_view_ber) << "%"
      << (other.views.empty()
              ? std::string()
              : std::string("<br><span class=\"small\">") +
                    (owner_first ? "blind " : "owner ") +
                    Printf("%.1f", 100 * other.mean_view_ber) + "% / " +
                    Printf("%.1f", 100 * other.p90_view_ber) + "%</span>")
      << "</td></tr>\n";
  }
  h << "</table></div>\n";

  // Files.
  h << "<h2>Files</h2>\n<table id=\"files\"><tr><th>Role</th><th>Path</th>"
       "<th class=\"num\">Size</th><th>FNV-1a 64</th></tr>\n";
  std::vector<ReportFile> files = {r.decoder};
  files.insert(files.end(), r.files.begin(), r.files.end());
  for (const ReportFile& f : files) {
    h << "<tr><td>" << HtmlEscape(f.role) << "</td><td><code>"
      << HtmlEscape(f.path) << "</code></td><td class=\"num\">" << f.bytes
      << " bytes</td><td><code>" << Hex(f.fnv1a) << "</code></td></tr>\n";
  }
  h << "</table>\n";

  // Commands.
  h << "<h2>Reproduce</h2>\n<p class=\"small\">With watergs installed and "
       "the files above (check their sizes and checksums), from the folder "
       "the report was made in:</p>\n";
  for (const ReportCommand& c : r.commands) {
    if (c.command.empty()) {
      h << "<p>" << HtmlEscape(c.caption) << ".</p>\n";
    } else {
      h << "<p>" << HtmlEscape(c.caption) << ":</p>\n<pre>"
        << CommandHtml(c.command) << "</pre>\n";
    }
  }
  if (!r.row_commands.empty()) {
    h << "<details><summary>The command behind each attack row</summary>\n";
    for (size_t k = 0; k < r.row_commands.size() && k < ev.robustness.size();
         ++k) {
      const RobustnessRow& row = ev.robustness[k];
      h << "<p>" << HtmlEscape(row.model) << ", " << HtmlEscape(row.attack)
        << ":</p>\n<pre>" << CommandHtml(r.row_commands[k]) << "</pre>\n";
    }
    h << "</details>\n";
  }

  // The data, for programs.
  nlohmann::json data;
  data["generator"] = r.generator;
  data["message"] = r.message_text;
  data["key_fingerprint"] = r.key_fingerprint;
  nlohmann::json files_json = nlohmann::json::array();
  for (const ReportFile& f : files) {
    files_json.push_back({{"role", f.role},
                          {"path", f.path},
                          {"bytes", f.bytes},
                          {"fnv1a", Hex(f.fnv1a)}});
  }
  data["files"] = files_json;
  data["claim"] = nlohmann::json::parse(ExtractionToJson(claim));
  data["evaluation"] = nlohmann::json::parse(EvaluationToJson(ev));
  // The decoder's outputs too: what a check of a listed command compares.
  for (size_t k = 0; k < ev.robustness.size(); ++k) {
    data["evaluation"]["robustness"][k]["mean_logits"] =
        ev.robustness[k].extraction.mean_logits;
  }
  nlohmann::json commands = nlohmann::json::array();
  for (const ReportCommand& c : r.commands) {
    commands.push_back({{"caption", c.caption}, {"command", c.command}});
  }
  data["commands"] = commands;
  data["row_commands"] = r.row_commands;
  std::string json = data.dump();
  // '<' appears only inside JSON strings, where \u003c means the same: the
  // block can then never close the script element early.
  std::string safe;
  for (const char c : json)
    safe += c == '<' ? std::string("\\u003c") : std::string(1, c);
  h << "<p class=\"small\">Made by " << HtmlEscape(r.generator)
    << ". The figures are also in this page's source as JSON "
       "(<code>watergs-report-data</code>).</p>\n"
    << "<script type=\"application/json\" id=\"watergs-report-data\">" << safe
    << "</script>\n</main>\n</body>\n</html>\n";
  return h.str();
}

}  // namespace watergs
