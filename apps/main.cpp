// relit: the command-line program.
#include "cli.hpp"

int main(int argc, char** argv) { return relit::cli::run(std::vector<std::string>(argv, argv + argc)); }
