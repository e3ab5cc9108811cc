// relit's log: one line per event on stderr, "[relit] message", filtered by level.
// The level comes from RELIT_LOG (debug, info, warning, error, off; default info) or set_log_level().
// Applications that have their own logging install a sink with set_log_sink().
#pragma once

#include <functional>
#include <string>

namespace relit {

enum class LogLevel { Debug = 0, Info = 1, Warning = 2, Error = 3, Off = 4 };

void set_log_level(LogLevel level);
LogLevel log_level();
/// Parses "debug" | "info" | "warning" | "error" | "off" (case-insensitive); throws InvalidArgument otherwise.
LogLevel parse_log_level(const std::string& name);

using LogSink = std::function<void(LogLevel, const std::string&)>;
/// Replaces the stderr sink; pass nullptr to restore it.
void set_log_sink(LogSink sink);

void log(LogLevel level, const std::string& message);
inline void log_debug(const std::string& m) { log(LogLevel::Debug, m); }
inline void log_info(const std::string& m) { log(LogLevel::Info, m); }
inline void log_warning(const std::string& m) { log(LogLevel::Warning, m); }

}  // namespace relit
