#include "apps/openvdb_messages.h"

#include <dlfcn.h>

#include <cstdio>
#include <cstring>
#include <iostream>
#include <mutex>
#include <string_view>
#include <utility>

#include <openvdb/openvdb.h>

#include <spacewarp/core/errors.h>

namespace spacewarp::cli {
namespace {

// log4cplus's C API (log4cplus/clogger.h, the same since log4cplus 2.0), declared here: its
// headers do not come with OpenVDB's.
using LogEventCallback = void (*)(void* cookie, const char* message, const char* loggerName,
                                  int level, const char* thread, const char* thread2,
                                  unsigned long long seconds, unsigned long microseconds,
                                  const char* file, const char* function, int line);
using StrConfigure = int (*)(const char* properties);
using AddCallbackAppender = int (*)(const char* logger, LogEventCallback callback, void* cookie);

std::mutex gMutex;
std::vector<std::string>* gCollector = nullptr;  ///< The live OpenVdbMessages' list, if any.

/// `text` as one printable line, without OpenVDB's level prefix and trailing white space.
std::string oneLine(std::string_view text) {
  for (const std::string_view prefix : {"WARNING: ", "WARN: "})
    if (text.substr(0, prefix.size()) == prefix) text.remove_prefix(prefix.size());
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' '))
    text.remove_suffix(1);
  return printable(text);
}

void deliver(std::string message) {
  const std::lock_guard<std::mutex> lock(gMutex);
  if (gCollector != nullptr) {
    gCollector->push_back(std::move(message));
  } else {
    std::fflush(stdout);
    std::fprintf(stderr, "spacewarp: warning: OpenVDB: %s\n", message.c_str());
  }
}

void onLogEvent(void* /*cookie*/, const char* message, const char* /*loggerName*/, int /*level*/,
                const char* /*thread*/, const char* /*thread2*/, unsigned long long /*seconds*/,
                unsigned long /*microseconds*/, const char* /*file*/, const char* /*function*/,
                int /*line*/) {
  deliver(oneLine(message != nullptr ? message : ""));
}

/// The function `name` from the libraries loaded so far, or null.
template <typename Function>
Function lookUp(const char* name) {
  void* symbol = ::dlsym(RTLD_DEFAULT, name);
  Function function = nullptr;
  static_assert(sizeof function == sizeof symbol);
  std::memcpy(&function, &symbol, sizeof function);
  return function;
}

void routeOpenVdbLog() {
  const auto configure = lookUp<StrConfigure>("log4cplus_str_configure");
  const auto addAppender = lookUp<AddCallbackAppender>("log4cplus_add_callback_appender");
  if (configure == nullptr || addAppender == nullptr) return;  // OpenVDB without log4cplus
  // Configuring the logger removes its appenders (OpenVDB's console appender); its level stays
  // at OpenVDB's default, warnings and worse.
  if (configure("log4cplus.logger.openvdb=WARN\n") != 0) return;
  addAppender("openvdb", onLogEvent, nullptr);
}

}  // namespace

OpenVdbMessages::OpenVdbMessages() {
  openvdb::initialize();  // before the appender is replaced: it adds OpenVDB's own, once
  static std::once_flag once;
  std::call_once(once, routeOpenVdbLog);
  {
    const std::lock_guard<std::mutex> lock(gMutex);
    previous_ = gCollector;
    gCollector = &messages_;
  }
  oldCerr_ = std::cerr.rdbuf(&cerrBuffer_);
}

OpenVdbMessages::~OpenVdbMessages() {
  std::cerr.rdbuf(oldCerr_);
  const std::lock_guard<std::mutex> lock(gMutex);
  gCollector = previous_;
}

std::vector<std::string> OpenVdbMessages::take() {
  std::vector<std::string> taken;
  {
    const std::lock_guard<std::mutex> lock(gMutex);
    taken.swap(messages_);
  }
  const std::string written = cerrBuffer_.str();
  cerrBuffer_.str("");
  std::size_t start = 0;
  while (start < written.size()) {
    std::size_t end = written.find('\n', start);
    if (end == std::string::npos) end = written.size();
    const std::string line = oneLine(std::string_view(written).substr(start, end - start));
    if (!line.empty()) taken.push_back(line);
    start = end + 1;
  }
  return taken;
}

}  // namespace spacewarp::cli
