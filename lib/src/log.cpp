// The process-wide log: level from RELIT_LOG, stderr by default, replaceable sink.
#include <relit/error.hpp>
#include <relit/log.hpp>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <iostream>
#include <mutex>

namespace relit {

namespace {
struct LogState {
  std::mutex mutex;
  LogLevel level = LogLevel::Info;
  LogSink sink;
  LogState() {
    if (const char* env = std::getenv("RELIT_LOG")) {
      try {
        level = parse_log_level(env);
      } catch (const InvalidArgument& e) {
        std::cerr << "[relit] warning: " << e.what() << "; using 'info'\n";
      }
    }
  }
};
LogState& state() {
  static LogState s;
  return s;
}
}  // namespace

LogLevel parse_log_level(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
  if (n == "debug") return LogLevel::Debug;
  if (n == "info") return LogLevel::Info;
  if (n == "warning" || n == "warn") return LogLevel::Warning;
  if (n == "error") return LogLevel::Error;
  if (n == "off" || n == "none" || n == "quiet") return LogLevel::Off;
  throw InvalidArgument("unknown log level '" + name + "' (RELIT_LOG): use debug, info, warning, error or off");
}

void set_log_level(LogLevel level) {
  std::lock_guard<std::mutex> lock(state().mutex);
  state().level = level;
}

LogLevel log_level() {
  std::lock_guard<std::mutex> lock(state().mutex);
  return state().level;
}

void set_log_sink(LogSink sink) {
  std::lock_guard<std::mutex> lock(state().mutex);
  state().sink = std::move(sink);
}

void log(LogLevel level, const std::string& message) {
  LogSink sink;
  {
    std::lock_guard<std::mutex> lock(state().mutex);
    if (level < state().level || level == LogLevel::Off) return;
    sink = state().sink;
  }
  if (sink) {
    sink(level, message);
    return;
  }
  const char* prefix = level == LogLevel::Warning ? "warning: " : level == LogLevel::Error ? "error: " : "";
  std::cerr << "[relit] " << prefix << message << '\n';
}

}  // namespace relit
