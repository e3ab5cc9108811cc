// relit: everything in one include.
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/cl/device.hpp>
#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/version.hpp>
