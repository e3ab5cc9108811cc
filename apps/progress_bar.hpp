// A progress bar for long operations on stderr: a redrawn bar with rate and ETA when stderr is a terminal,
// plain lines every few seconds otherwise (logs, CI). Use it as a relit::ProgressCallback.
#pragma once

#include <relit/progress.hpp>

#include <chrono>
#include <string>

namespace relit::cli {

class ProgressBar {
 public:
  /// `label` prefixes every line ("generate"); `interval` is the seconds between plain lines.
  explicit ProgressBar(std::string label, double interval = 5.0);
  ~ProgressBar();
  /// Draws `p`; always returns true (the bar never cancels).
  bool operator()(const Progress& p);
  /// Ends the bar's line (also done by the destructor).
  void finish();

  /// "1.2M", "345k", "12": a count with an SI suffix.
  static std::string si(double value);
  /// "1:02:03", "4:05": seconds as h:mm:ss or m:ss.
  static std::string clock(double seconds);
  /// "12.3k samples/s", or below one per second "4.20 s/view" (the unit's plural 's' dropped).
  static std::string rate(double per_second, const std::string& unit);

 private:
  std::string m_label;
  double m_interval;
  bool m_tty;
  bool m_open = false;
  double m_last = -1e9;
};

}  // namespace relit::cli
