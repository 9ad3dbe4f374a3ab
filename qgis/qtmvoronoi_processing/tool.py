"""Runs the installed qtmvoronoi: its progress on stderr drives Processing's progress bar, a
cancel stops it with SIGINT (it then leaves no output behind), and its messages and exit status
reach the Processing log."""

import os
import queue
import shutil
import signal
import subprocess
import threading

from qgis.core import QgsProcessingException

TOOL_ENV = "QTMVORONOI"  # the tool's path, when it is not on PATH


def find_tool():
    """The qtmvoronoi executable, or None."""
    path = os.environ.get(TOOL_ENV)
    if path:
        return path if os.access(path, os.X_OK) else None
    return shutil.which("qtmvoronoi")


def tool_version():
    """The tool's --version line, or an empty string."""
    tool = find_tool()
    if tool is None:
        return ""
    try:
        out = subprocess.run([tool, "--version"], capture_output=True, text=True, timeout=30)
        return out.stdout.strip().split()[-1] if out.returncode == 0 and out.stdout.strip() else ""
    except (OSError, subprocess.SubprocessError):
        return ""


class ProgressReader:
    """Reads GDAL's terminal progress ("0...10...20...") and the tool's message lines."""

    def __init__(self):
        self.percent = 0.0
        self.number = ""
        self.line = ""
        self.messages = []

    def feed(self, text):
        for ch in text:
            if self.line or ch == "q":  # a message line ("qtmvoronoi: ...") runs to its newline
                if ch == "\n":
                    self.messages.append(self.line)
                    self.line = ""
                else:
                    self.line += ch
            elif ch.isdigit():
                self.number += ch
            elif ch == ".":
                self._end_number()
                self.percent = min(100.0, self.percent + 2.5)
            elif ch == "\n":
                self._end_number()
            elif not ch.isspace():
                self.line = ch  # some other text: keep it as a message

    def _end_number(self):
        if self.number:
            self.percent = float(self.number)
            self.number = ""

    def finish(self):
        self._end_number()
        if self.line:
            self.messages.append(self.line)
            self.line = ""


def run_tool(arguments, feedback):
    """Runs qtmvoronoi with `arguments` (after -progress); raises QgsProcessingException when it
    fails or is cancelled."""
    tool = find_tool()
    if tool is None:
        raise QgsProcessingException("qtmvoronoi was not found: install the qtmvoronoi package, or set "
                                     + TOOL_ENV + " to the tool's path")
    command = [tool, "-progress"] + [str(a) for a in arguments]
    feedback.pushCommandInfo(" ".join(_quoted(c) for c in command))
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    chunks = queue.Queue()

    def read_stderr():
        while True:
            data = os.read(process.stderr.fileno(), 4096)
            if not data:
                break
            chunks.put(data.decode("utf-8", "replace"))
        chunks.put(None)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    progress = ProgressReader()
    reported = 0
    cancelled = False
    done = False
    while not done:
        try:
            chunk = chunks.get(timeout=0.1)
        except queue.Empty:
            chunk = ""
        if chunk is None:
            done = True
        elif chunk:
            progress.feed(chunk)
            feedback.setProgress(progress.percent)
        for message in progress.messages[reported:]:
            feedback.pushInfo(message)
        reported = len(progress.messages)
        if feedback.isCanceled() and not cancelled:
            cancelled = True
            process.send_signal(signal.SIGINT)  # the tool stops at its next step and removes its output
    status = process.wait()
    reader.join()
    process.stderr.close()
    progress.finish()
    for message in progress.messages[reported:]:
        feedback.pushInfo(message)
    if cancelled:
        raise QgsProcessingException("qtmvoronoi was cancelled (exit status %d); it wrote nothing" % status)
    if status != 0:
        errors = [m for m in progress.messages if m.startswith("qtmvoronoi:")] or progress.messages
        detail = errors[-1] if errors else "no message"
        for message in errors:
            feedback.reportError(message)
        raise QgsProcessingException("qtmvoronoi failed (exit status %d): %s" % (status, detail))


def _quoted(text):
    return text if text and all(c.isalnum() or c in "-_./:,=+" for c in text) else "'" + text.replace("'", "'\\''") + "'"
