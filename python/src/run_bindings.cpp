// run_voronoi (src/voronoi.hpp) for Python: the run works with the GIL released; its progress
// callback takes the GIL back to check for Ctrl-C (PyErr_CheckSignals), call the Python progress
// callable and hand over the messages the run's threads queued; an exception there, or a callable
// returning False, stops the run cleanly (the library's Interrupted: nothing is left behind), and
// the exception is raised once the run has undone its work.
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "voronoi.hpp"

namespace qtmv::python {

namespace {

// What the run's threads share with the calling Python thread. The library may keep copies of
// the callbacks beyond the run (the trace channel's sink is a process-wide slot), so the
// callbacks hold only this, which owns no Python object and, once closed, calls nothing.
class Bridge {
 public:
  Bridge(py::handle progress, py::handle messages) : progress_(progress), messages_(messages) {}

  // Any thread, GIL or not: queued, handed to Python on the next progress call or at the end.
  void message(Severity severity, const std::string& text) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (open_) pending_.emplace_back(severity, text);
  }

  // The run's progress (any thread): false stops the run.
  bool progress(double fraction, const char* stage) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!open_) return true;
    }
    py::gil_scoped_acquire gil;
    if (stopped()) return false;
    try {
      deliver();
      // Ctrl-C: Python's handler has only set a flag; here, on the main thread, it raises.
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      const std::string name = stage ? stage : "";
      if (progress_ && (stage_ != name || fraction >= last_fraction_ + 0.001 || fraction >= 1.0)) {
        stage_ = name;
        last_fraction_ = fraction;
        const py::object answer = progress_(fraction, name);
        if (!answer.is_none() && !py::bool_(answer)) {
          stopped_by_callback_ = true;
          return false;
        }
      }
    } catch (py::error_already_set& e) {
      error_ = std::move(e);
      return false;
    }
    return true;
  }

  // With the GIL released, once the run has returned: nothing of Python is called any more.
  void close() {
    const std::lock_guard<std::mutex> lock(mutex_);
    open_ = false;
  }

  // With the GIL: the messages still queued go to Python (after close: the last of the run's).
  void deliver() {
    std::vector<std::pair<Severity, std::string>> batch;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      batch.swap(pending_);
    }
    if (!messages_) return;
    for (const auto& [severity, text] : batch) {
      const char* name = severity == Severity::warning ? "warning" : severity == Severity::debug ? "debug" : "info";
      messages_(name, text);
    }
  }

  bool stopped() const { return stopped_by_callback_ || error_.has_value(); }
  bool stopped_by_callback() const { return stopped_by_callback_; }
  // The Python exception that stopped the run, if one did (GIL held).
  std::optional<py::error_already_set>& error() { return error_; }

 private:
  std::mutex mutex_;
  bool open_ = true;
  std::vector<std::pair<Severity, std::string>> pending_;
  // Touched only with the GIL held.
  py::handle progress_, messages_;  // borrowed: run() holds them for the run's length
  std::string stage_;
  double last_fraction_ = -1.0;
  bool stopped_by_callback_ = false;
  std::optional<py::error_already_set> error_;
};

VoronoiSummary run(const std::string& source, const std::string& destination, VoronoiOptions options,
                   const py::object& progress, const py::object& messages) {
  if (!progress.is_none() && !PyCallable_Check(progress.ptr())) throw py::type_error("progress: not callable");
  if (!messages.is_none() && !PyCallable_Check(messages.ptr())) throw py::type_error("messages: not callable");
  auto bridge = std::make_shared<Bridge>(progress.is_none() ? py::handle() : py::handle(progress),
                                         messages.is_none() ? py::handle() : py::handle(messages));
  options.progress = [bridge](double fraction, const char* stage) { return bridge->progress(fraction, stage); };
  options.messages = [bridge](Severity severity, const std::string& text) { bridge->message(severity, text); };
  VoronoiSummary summary;
  std::string failure;
  bool interrupted = false;
  {
    py::gil_scoped_release release;
    try {
      summary = run_voronoi(source, destination, options);
    } catch (const Interrupted&) {
      interrupted = true;
    } catch (const std::exception& e) {
      failure = e.what();
    }
    bridge->close();
    options = VoronoiOptions{};  // the callbacks' copies go without the GIL: they own no Python object
  }
  // The run's last messages (its warnings before a failure too), then its outcome.
  try {
    bridge->deliver();
  } catch (py::error_already_set& e) {
    if (!bridge->error()) bridge->error() = std::move(e);
  }
  if (bridge->error()) {
    py::error_already_set e = std::move(*bridge->error());
    bridge->error().reset();
    throw e;
  }
  if (interrupted) {
    raise(exceptions().interrupted, bridge->stopped_by_callback()
                                        ? "stopped by the progress callback: '" + destination + "' not written"
                                        : "interrupted: '" + destination + "' not written");
  }
  if (!failure.empty()) raise(exceptions().error, failure);
  return summary;
}

}  // namespace

void bind_run(py::module_& m) {
  m.def("run_voronoi", &run, py::arg("source"), py::arg("destination"), py::arg("options"), py::arg("progress") = py::none(),
        py::arg("messages") = py::none(),
        R"(Runs the pipeline from source (any OGR dataset name) to destination (a GDAL file name), as the tool does.

options: VoronoiOptions. progress: None, or a callable (fraction 0..1, stage name) whose False
stops the run. messages: None, or a callable (severity 'info' | 'warning' | 'debug', text) for
the tool's informative lines, warnings and QTMV_TRACE lines. The GIL is released while the run
works; Ctrl-C (KeyboardInterrupt), an exception of a callable or progress' False stop it
cleanly (the destination untouched, no temporary file left) and the exception is raised:
KeyboardInterrupt, the callable's own, or qtmvoronoi.Interrupted. A failed run raises
qtmvoronoi.Error with the tool's message. Returns a VoronoiSummary.)");
}

}  // namespace qtmv::python
