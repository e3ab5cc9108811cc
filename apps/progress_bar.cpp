// Progress bar on stderr (see progress_bar.hpp).
#include "progress_bar.hpp"

#include <relit/parallel.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <unistd.h>

namespace relit::cli {

ProgressBar::ProgressBar(std::string label, double interval)
    : m_label(std::move(label)), m_interval(interval), m_tty(::isatty(STDERR_FILENO) != 0) {}

ProgressBar::~ProgressBar() { finish(); }

std::string ProgressBar::si(double v) {
  char buf[32];
  if (v >= 1e9)
    std::snprintf(buf, sizeof buf, "%.2fG", v / 1e9);
  else if (v >= 1e6)
    std::snprintf(buf, sizeof buf, "%.2fM", v / 1e6);
  else if (v >= 1e3)
    std::snprintf(buf, sizeof buf, "%.1fk", v / 1e3);
  else
    std::snprintf(buf, sizeof buf, v < 10 ? "%.1f" : "%.0f", v);  // 1.4 views/s, not "1 views/s"
  return buf;
}

std::string ProgressBar::rate(double per_second, const std::string& unit) {
  if (!(per_second > 0) || !std::isfinite(per_second)) return "- " + unit + "/s";
  if (per_second >= 1) return si(per_second) + " " + unit + "/s";
  // Slow work (a view that takes 40 s) reads as seconds per item, not "0 views/s".
  const std::string one = unit.size() > 1 && unit.back() == 's' ? unit.substr(0, unit.size() - 1) : unit;
  char buf[32];
  std::snprintf(buf, sizeof buf, 1 / per_second < 10 ? "%.2f" : "%.1f", 1 / per_second);
  return std::string(buf) + " s/" + one;
}

std::string ProgressBar::clock(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

bool ProgressBar::operator()(const Progress& p) {
  if (parallel::rank() != 0) return true;  // one bar per job: rank 0's
  const bool last = p.total && p.done >= p.total;
  if (!m_tty && !last && p.elapsed - m_last < m_interval) return true;
  m_last = p.elapsed;
  std::ostringstream line;
  const double f = p.fraction();
  if (m_tty) {
    const int width = 30, filled = int(f * width);
    line << '\r' << m_label << " [" << std::string(filled, '#') << std::string(width - filled, '.') << "] ";
  } else {
    line << m_label << ": ";
  }
  char pct[16];
  std::snprintf(pct, sizeof pct, "%5.1f%%", 100.0 * f);
  line << pct << "  " << rate(p.rate, p.unit) << "  elapsed " << clock(p.elapsed) << "  ETA "
       << (p.rate > 0 ? clock(p.eta) : std::string("?"));
  if (!p.message.empty()) line << "  " << p.message;
  if (m_tty) {
    line << "\x1b[K";  // clear what a longer previous line left
    std::cerr << line.str() << std::flush;
    m_open = true;
  } else {
    std::cerr << line.str() << std::endl;
  }
  return true;
}

void ProgressBar::finish() {
  if (m_open) std::cerr << std::endl;
  m_open = false;
}

}  // namespace relit::cli
