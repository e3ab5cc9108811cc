// relit: the command-line program. Under an MPI launcher (mpirun -np N relit ...) every rank runs it: rank 0
// prints and writes, the others compute their share silently (docs/scaling.md).
#include "cli.hpp"

#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/parallel.hpp>

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <streambuf>
#include <string>
#include <unistd.h>

namespace {
class NullBuffer : public std::streambuf {
 protected:
  int overflow(int c) override { return c; }
};
// mpirun stops the surviving ranks with SIGTERM when one dies: each says so before it goes. Every file relit writes
// is replaced atomically, so the last checkpoint is whole.
char g_stopped_message[256];
extern "C" void on_stopped_by_launcher(int) {
  const ssize_t ignored = ::write(STDERR_FILENO, g_stopped_message, std::strlen(g_stopped_message));
  (void)ignored;
  ::_exit(143);
}

void say_why_when_stopped() {
  const std::string text = "relit: error: " + relit::parallel::rank_prefix() +
                           "stopped by the MPI launcher: another rank failed or was killed (its own message says why). "
                           "What relit wrote is whole (every file is replaced atomically); a training run continues "
                           "with relit train --resume\n";
  std::strncpy(g_stopped_message, text.c_str(), sizeof g_stopped_message - 1);
  std::signal(SIGTERM, on_stopped_by_launcher);
}
}  // namespace

int main(int argc, char** argv) {
  try {
    relit::parallel::init();
  } catch (const std::exception& e) {
    std::cerr << "relit: error: " << relit::parallel::rank_prefix() << e.what() << '\n';
    relit::parallel::abort_job(1);
    return 1;
  }
  if (relit::parallel::distributed()) say_why_when_stopped();
  static NullBuffer null;  // outlives std::cout's flush at exit
  if (relit::parallel::rank() != 0) {
    std::cout.rdbuf(&null);  // results are rank 0's to print; errors and warnings still reach stderr
    if (!std::getenv("RELIT_LOG")) relit::set_log_level(relit::LogLevel::Warning);
  }
  const int code = relit::cli::run(std::vector<std::string>(argv, argv + argc));
  // A rank that failed ends the job: the others may be waiting for it in a collective.
  if (code != 0) relit::parallel::abort_job(code);
  relit::parallel::finalize();
  return code;
}
