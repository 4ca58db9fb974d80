"""JupyterLab in a real browser for the browser tests: a server on loopback, Chromium driven by Playwright.

`JupyterLab` starts ``jupyter lab`` on 127.0.0.1 with a free port, no token and a temporary root
(its settings, workspaces and runtime files live there too), and stops it by its PID. `chromium`
finds a Chromium executable and `browser_context` opens one with a fresh profile. `Notebook`
drives one notebook in a JupyterLab page: run all cells, wait for the kernel, find a cell by its
source, screenshot an element and measure what it shows.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np

#: Chromium switches for a headless run as root on a machine with no outside network.
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def chromium() -> str | None:
    """Path of a Chromium (or Chrome) executable: ``$CHROMIUM``, else the first one on ``PATH``."""
    named = os.environ.get("CHROMIUM")
    if named:
        return named
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class JupyterLab:
    """A JupyterLab server on 127.0.0.1 serving ``root``; a context manager that stops it by its PID.

    Parameters
    ----------
    root : Path
        Directory the server serves (copy the notebooks there); its settings, workspaces and
        runtime files go to ``root / ".lab"``.
    env : dict, optional
        Extra environment variables for the server and so for its kernels (None: remove it).
    timeout : float
        Seconds to wait for the server to answer.
    """

    def __init__(self, root: Path, *, env: dict | None = None, timeout: float = 60.0):
        self.root = Path(root)
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        state = self.root / ".lab"
        for sub in ("config", "runtime", "settings", "workspaces"):
            (state / sub).mkdir(parents=True, exist_ok=True)
        self.log_path = state / "server.log"
        news = state / "settings" / "@jupyterlab" / "apputils-extension" / "notification.jupyterlab-settings"
        news.parent.mkdir(parents=True, exist_ok=True)
        news.write_text(json.dumps({"fetchNews": "false", "checkForUpdates": False}))  # no toast over the page
        environ = {**os.environ, "JUPYTER_CONFIG_DIR": str(state / "config"),
                   "JUPYTER_RUNTIME_DIR": str(state / "runtime"), "PYTHONUNBUFFERED": "1", **(env or {})}
        environ = {key: value for key, value in environ.items() if value is not None}
        command = [sys.executable, "-m", "jupyterlab", "--no-browser", "--ip", "127.0.0.1",
                   "--port", str(self.port), "--port-retries", "0", f"--ServerApp.root_dir={self.root}",
                   "--IdentityProvider.token=", "--ServerApp.password=",
                   f"--LabApp.user_settings_dir={state / 'settings'}",
                   f"--LabApp.workspaces_dir={state / 'workspaces'}",
                   "--LabApp.news_url=None", "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate"]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            command.append("--allow-root")  # CI runs as root
        with open(self.log_path, "wb") as log:
            # its own process group: the kernels it starts can be ended with it
            self.process = subprocess.Popen(command, cwd=self.root, env=environ, stdout=log,
                                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                            start_new_session=True)
        try:
            self._wait(timeout)
        except BaseException:
            self.stop()
            raise

    def _wait(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"JupyterLab exited with {self.process.returncode}:\n{self.log()}")
            try:
                with urllib.request.urlopen(f"{self.url}/api/status", timeout=2) as answer:
                    if answer.status == 200:
                        return
            except (urllib.error.URLError, OSError):
                pass
            time.sleep(0.25)
        raise TimeoutError(f"JupyterLab did not answer within {timeout:g} s:\n{self.log()}")

    def log(self) -> str:
        """The server's output so far (its last 4,000 characters)."""
        try:
            return self.log_path.read_text(errors="replace")[-4000:]
        except OSError:
            return ""

    def request(self, method: str, path: str):
        """Send a REST request to the server; returns the decoded JSON answer or None."""
        request = urllib.request.Request(f"{self.url}{path}", method=method)
        with urllib.request.urlopen(request, timeout=10) as answer:
            body = answer.read()
        return json.loads(body) if body else None

    def shutdown_kernels(self) -> None:
        """End every kernel the server runs (the server stays up)."""
        for kernel in self.request("GET", "/api/kernels"):
            with contextlib.suppress(urllib.error.URLError, OSError):
                self.request("DELETE", f"/api/kernels/{kernel['id']}")

    def stop(self, timeout: float = 20.0) -> None:
        """Stop the server by its PID (SIGTERM, then SIGKILL), then whatever is left of its process group."""
        pid = self.process.pid
        if self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                self.process.wait(timeout)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(pid, signal.SIGKILL)  # kernels it did not end; the group is the server's own

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


@contextlib.contextmanager
def browser_context(executable: str, profile: Path, *, width: int = 1280, height: int = 900):
    """A Playwright browser context of headless Chromium with a fresh profile in ``profile``."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(profile), executable_path=executable, headless=True, args=CHROMIUM_ARGS,
            viewport={"width": width, "height": height})
        try:
            yield context
        finally:
            context.close()


def decode_png(data: bytes) -> np.ndarray:
    """An (h, w, 3) uint8 RGB array from PNG bytes."""
    from PIL import Image

    with Image.open(io.BytesIO(data)) as image:
        return np.asarray(image.convert("RGB"))


def coloured_fraction(rgb: np.ndarray, saturation: int = 60) -> float:
    """Fraction of pixels that are clearly coloured (max - min channel > ``saturation``), not white, grey or black."""
    rgb = rgb.astype(int)
    return float(np.mean(rgb.max(axis=2) - rgb.min(axis=2) > saturation))


def changed_fraction(a: np.ndarray, b: np.ndarray, tolerance: int = 16) -> float:
    """Fraction of pixels that differ by more than ``tolerance`` in some channel (1.0 if the sizes differ)."""
    if a.shape != b.shape:
        return 1.0
    return float(np.mean(np.abs(a.astype(int) - b.astype(int)).max(axis=2) > tolerance))


class Notebook:
    """A notebook open in a JupyterLab page.

    Parameters
    ----------
    page : playwright.sync_api.Page
        A page of the browser context.
    lab : JupyterLab
        The server.
    name : str
        The notebook's file name in the server's root.
    shots : Path
        Directory for the screenshots.

    Attributes
    ----------
    console_errors : list of str
        Every console error and uncaught page error since the page opened.
    """

    def __init__(self, page, lab: JupyterLab, name: str, shots: Path):
        self.page, self.lab, self.name, self.shots = page, lab, name, Path(shots)
        self.console_errors: list[str] = []
        page.on("console", lambda message: message.type == "error" and self.console_errors.append(
            f"console: {message.text}"))
        page.on("pageerror", lambda error: self.console_errors.append(f"page error: {error}"))
        workspace = re.sub(r"\W", "-", Path(name).stem)
        page.goto(f"{lab.url}/lab/workspaces/{workspace}/tree/{name}", wait_until="domcontentloaded")
        self.panel = page.locator(".jp-NotebookPanel:visible")
        self.panel.locator(".jp-Cell").first.wait_for(timeout=60_000)
        self.wait_idle(timeout=60)

    def wait_idle(self, timeout: float = 120) -> None:
        """Wait until a kernel is connected and idle (the status bar and the notebook's indicator agree for 1 s)."""
        deadline = time.monotonic() + timeout
        idle_since = None
        while True:
            status = self.panel.locator(".jp-Notebook-ExecutionIndicator").get_attribute("data-status")
            bar = self.page.locator("#jp-main-statusbar").inner_text()
            if status == "idle" and re.search(r"\| Idle\b", bar) and "No Kernel" not in bar:
                idle_since = idle_since or time.monotonic()
                if time.monotonic() - idle_since >= 1.0:
                    return
            else:
                idle_since = None
            if time.monotonic() > deadline:
                raise TimeoutError(f"kernel not idle after {timeout:g} s: {status!r}, status bar {bar!r}")
            self.page.wait_for_timeout(200)

    def command(self, menu: str, item: str) -> None:
        """Run a command from the main menu bar, as a person would."""
        self.page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(rf"^{re.escape(menu)}$")).click()
        self.page.locator(".lm-Menu-item:visible .lm-Menu-itemLabel",
                          has_text=re.compile(rf"^{re.escape(item)}$")).click()

    def run_all(self, timeout: float = 300) -> float:
        """Run > Run All Cells, wait until every code cell has run; returns the seconds it took.

        Raises AssertionError, with what the page and the server said, if the run stops short (a
        cell failed, the kernel died) or takes longer than ``timeout`` s.
        """
        start = time.monotonic()
        self.command("Run", "Run All Cells")
        cells = self.panel.locator(".jp-CodeCell")
        count = cells.count()
        stalled_since = None
        while True:
            prompts = [cells.nth(i).locator(".jp-InputPrompt").text_content().strip() for i in range(count)]
            if all(re.fullmatch(r"\[\d+\]:", p) for p in prompts):
                break
            # nothing running or queued, yet not all run: a cell failed or the kernel went away
            stalled = time.monotonic() - start > 5 and "[*]:" not in prompts
            stalled_since = (stalled_since or time.monotonic()) if stalled else None
            if stalled_since and time.monotonic() - stalled_since > 5 or time.monotonic() - start > timeout:
                raise AssertionError(self._report(f"the run stopped short after {time.monotonic() - start:.0f} s: "
                                                  f"{prompts}"))
            self.page.wait_for_timeout(250)
        self.wait_idle()
        return time.monotonic() - start

    def _report(self, what: str) -> str:
        status = self.page.locator("#jp-main-statusbar").inner_text().replace("\n", " ")
        return "\n".join([what, f"status bar: {status}", *self.errors_in_outputs(), *self.console_errors,
                          "server log:", self.lab.log()[-1500:]])

    def errors_in_outputs(self) -> list[str]:
        """The text of every error output (a traceback) in the notebook."""
        errors = self.panel.locator(".jp-OutputArea-output[data-mime-type='application/vnd.jupyter.stderr'],"
                                    ".jp-RenderedText[data-mime-type='application/vnd.jupyter.error']")
        return [errors.nth(i).inner_text()[:2000] for i in range(errors.count())
                if "Traceback" in errors.nth(i).inner_text() or "Error" in errors.nth(i).inner_text()]

    def cell(self, source_fragment: str):
        """The code cell whose source (in the notebook's file) contains ``source_fragment``."""
        notebook = json.loads((self.lab.root / self.name).read_text())
        sources = ["".join(c["source"]) for c in notebook["cells"] if c["cell_type"] == "code"]
        found = [i for i, source in enumerate(sources) if source_fragment in source]
        if len(found) != 1:
            raise LookupError(f"{len(found)} code cells contain {source_fragment!r}")
        return self.panel.locator(".jp-CodeCell").nth(found[0])

    def shot(self, locator, name: str) -> np.ndarray:
        """Screenshot ``locator`` into ``shots/<notebook>-<name>.png``; returns it as RGB."""
        locator.scroll_into_view_if_needed()
        path = self.shots / f"{Path(self.name).stem}-{name}.png"
        data = locator.screenshot(path=str(path), animations="disabled")
        return decode_png(data)

    def page_shot(self, name: str) -> None:
        """Screenshot the whole page into ``shots/<notebook>-<name>.png``."""
        self.page.screenshot(path=str(self.shots / f"{Path(self.name).stem}-{name}.png"))
