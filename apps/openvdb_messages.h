#pragma once
// What OpenVDB logs while the tool reads or writes a volume, caught so that the tool prints it
// as its own warnings ("spacewarp: warning: in.vdb: ...") instead of OpenVDB printing it itself.

#include <sstream>
#include <streambuf>
#include <string>
#include <vector>

namespace spacewarp::cli {

/// Collects OpenVDB's messages from its construction to take(). OpenVDB logs two ways:
///
/// - Its compiled code (libopenvdb, built with log4cplus by Debian) logs through log4cplus to
///   the logger "openvdb", whose appender openvdb::initialize() sets to write coloured lines
///   ("\033[35m WARN: ...") to stdout, mixed with the tool's output. The first OpenVdbMessages
///   replaces that appender, for the rest of the process, with one that hands each message to
///   the live OpenVdbMessages (or, when there is none, prints it at once as a warning). This
///   uses log4cplus's C API (log4cplus_str_configure, log4cplus_add_callback_appender), looked
///   up at run time in the libraries OpenVDB brought in, so that the tool needs neither
///   log4cplus's headers nor a direct link to it; when OpenVDB was built without log4cplus the
///   functions are not there and nothing is replaced.
/// - Its header-only code, compiled into the tool without log4cplus (OpenVDB's CMake module does
///   not tell its users about it), writes "WARNING: ..." lines to std::cerr. While an
///   OpenVdbMessages lives, std::cerr writes into it. (Process-wide: fine for the tool, which
///   reads and writes volumes on its main thread and writes nothing else to std::cerr.)
class OpenVdbMessages {
 public:
  /// Calls openvdb::initialize(), replaces OpenVDB's log appender (once) and starts collecting.
  OpenVdbMessages();
  /// Stops collecting (std::cerr back as it was); messages not taken are dropped.
  ~OpenVdbMessages();
  OpenVdbMessages(const OpenVdbMessages&) = delete;
  OpenVdbMessages& operator=(const OpenVdbMessages&) = delete;

  /// The messages so far, oldest first, each one printable line without OpenVDB's level prefix
  /// ("unsupported VDB file format (expected version 224 or earlier, got version 225)"), and
  /// forgets them.
  std::vector<std::string> take();

 private:
  std::vector<std::string> messages_;             ///< From log4cplus, under the module's mutex.
  std::vector<std::string>* previous_ = nullptr;  ///< An enclosing OpenVdbMessages' list.
  std::stringbuf cerrBuffer_;
  std::streambuf* oldCerr_ = nullptr;
};

}  // namespace spacewarp::cli
