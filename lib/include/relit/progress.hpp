// Progress of a long operation (path tracing, dataset generation, training, benchmarks), reported through a
// callback. The callback returns false to cancel: the operation then stops at its next check and throws
// relit::Cancelled, leaving no partial output behind.
//
//   relit::ProgressCallback cb = [](const relit::Progress& p) {
//     std::cerr << p.done << "/" << p.total << " ETA " << p.eta << " s\n";
//     return true;                                    // keep going
//   };
#pragma once

#include <relit/error.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace relit {

struct Progress {
  std::uint64_t done = 0;   ///< units finished (samples, images, steps: see `unit`)
  std::uint64_t total = 0;  ///< units in all (0 when unknown)
  double elapsed = 0.0;     ///< seconds since the operation started
  double rate = 0.0;        ///< units per second so far
  double eta = 0.0;         ///< seconds left at the current rate (0 when unknown)
  std::string unit;         ///< what is counted ("samples", "views")
  std::string message;      ///< what is being done now ("train/r_012")
  double fraction() const { return total ? double(done) / double(total) : 0.0; }
};

/// Returns false to cancel the operation.
using ProgressCallback = std::function<bool(const Progress&)>;

/// Thrown when a progress callback asked to stop.
class Cancelled : public Error {
 public:
  using Error::Error;
};

/// Keeps time for an operation and calls its callback (if any) with rate and ETA filled in.
class ProgressTracker {
 public:
  ProgressTracker(ProgressCallback callback, std::uint64_t total, std::string unit)
      : m_callback(std::move(callback)), m_start(std::chrono::steady_clock::now()) {
    m_progress.total = total;
    m_progress.unit = std::move(unit);
  }
  /// Records `done` units and reports; throws Cancelled when the callback returns false.
  void update(std::uint64_t done, const std::string& message = "") {
    m_progress.done = done;
    m_progress.message = message;
    m_progress.elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    m_progress.rate = m_progress.elapsed > 0 ? double(done) / m_progress.elapsed : 0.0;
    m_progress.eta =
        (m_progress.rate > 0 && m_progress.total >= done) ? double(m_progress.total - done) / m_progress.rate : 0.0;
    if (m_callback && !m_callback(m_progress))
      throw Cancelled("cancelled by the progress callback at " + std::to_string(done) + " of " +
                      std::to_string(m_progress.total) + " " + m_progress.unit);
  }
  const Progress& progress() const { return m_progress; }

 private:
  ProgressCallback m_callback;
  std::chrono::steady_clock::time_point m_start;
  Progress m_progress;
};

}  // namespace relit
