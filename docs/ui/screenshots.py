"""Redraw the README's screenshots of the MLflow UI (docs/ui/*.png) with headless Chromium.

    python docs/ui/screenshots.py STORE_DIR      # STORE_DIR: where a sweep logged (STORE_DIR/mlflow.db)

Starts ``maglev ui`` on ``STORE_DIR/mlflow.db`` (a free port) and drives one headless
Chromium through the DevTools protocol (``aiohttp``, which MLflow requires): the URL
``maglev ui`` prints (the latest sweep's runs table), the best model run and the ranking
run, with MLflow's assistant panel closed and each description unfolded ("Show more").
Writes ``runs.png``, ``model_run.png`` and ``ranking_run.png`` beside this script, in 256
colours so they stay small.  The README's shots come from the lab sweep::

    python study.py -m +sweep=lab tracking.uri=sqlite:///$STORE/mlflow.db \\
        tracking.artifact_location=$STORE/artifacts hydra.sweep.dir=$STORE/multirun
    python docs/ui/screenshots.py $STORE
"""

from __future__ import annotations

import asyncio
import base64
import io
import json
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
CLOSED_ASSISTANT = {"mlflow.assistant.fab.autoOpenedOnFirstLoad_v1": "true", "mlflow.assistant.panelOpen_v1": "false"}
UNFOLD = ("[...document.querySelectorAll('*')].filter(e => !e.childElementCount && e.textContent.trim() === "
          "'Show more').forEach(e => e.click())")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_ui(uri: str, port: int) -> tuple[subprocess.Popen, str]:
    """``maglev ui`` as a process and the URL it prints."""
    proc = subprocess.Popen([sys.executable, "-m", "maglev", "ui", "--tracking-uri", uri, "--port", str(port)],
                            stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        found = re.search(r"MLflow UI: (\S+)", line)
        if found:
            return proc, found.group(1)
    raise SystemExit(f"maglev ui exited ({proc.wait()}) without printing a URL")


class Browser:
    """One page of a headless Chromium, driven through the DevTools protocol."""

    def __init__(self, ws) -> None:
        self.ws, self.n = ws, 0

    async def call(self, method: str, **params) -> dict:
        self.n += 1
        await self.ws.send_json({"id": self.n, "method": method, "params": params})
        async for msg in self.ws:
            data = json.loads(msg.data)
            if data.get("id") == self.n:
                if "error" in data:
                    raise RuntimeError(f"{method}: {data['error']}")
                return data["result"]
        raise RuntimeError("the browser closed the connection")

    async def js(self, expression: str):
        return (await self.call("Runtime.evaluate", expression=expression, returnByValue=True))["result"].get("value")

    async def open(self, url: str, until: str, timeout: float = 90.0) -> None:
        """Load ``url`` and wait until the page shows the text ``until`` (and a little longer for the rest)."""
        await self.call("Page.navigate", url=url)
        for _ in range(int(timeout / 0.5)):
            if await self.js(f"!!document.body && document.body.innerText.includes({json.dumps(until)})"):
                await asyncio.sleep(3)
                return
            await asyncio.sleep(0.5)
        raise RuntimeError(f"{url} did not show {until!r} within {timeout:g} s")

    async def shoot(self, out: Path, width: int, height: int) -> None:
        from PIL import Image

        await self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                        mobile=False)
        await asyncio.sleep(1)
        png = base64.b64decode((await self.call("Page.captureScreenshot", format="png"))["data"])
        Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=256).save(out, optimize=True)
        print(f"{out.name}: {out.stat().st_size // 1024} kB")


async def shoot_all(chromium: str, base: str, shots: list[tuple[str, str, str, int, int]]) -> None:
    """``shots``: (file name, URL, text the page shows when loaded, width, height)."""
    import aiohttp

    with tempfile.TemporaryDirectory(prefix="maglev-chromium-") as profile:
        proc = subprocess.Popen([chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                                 "--no-first-run", "--disable-background-networking", "--remote-debugging-port=0",
                                 f"--user-data-dir={profile}", "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            port_file = Path(profile) / "DevToolsActivePort"
            for _ in range(300):
                if port_file.is_file() and port_file.read_text().strip():
                    break
                await asyncio.sleep(0.1)
            port = port_file.read_text().split()[0]
            async with aiohttp.ClientSession() as session:
                async with session.get(f"http://127.0.0.1:{port}/json/list") as r:
                    page = next(t for t in await r.json() if t["type"] == "page")
                async with session.ws_connect(page["webSocketDebuggerUrl"], max_msg_size=0) as ws:
                    browser = Browser(ws)
                    await browser.call("Page.navigate", url=f"{base}/health")  # the UI's origin, for its storage
                    await asyncio.sleep(1)
                    for key, value in CLOSED_ASSISTANT.items():
                        await browser.js(f"localStorage.setItem({json.dumps(key)}, {json.dumps(value)})")
                    for name, url, until, width, height in shots:
                        await browser.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                                           deviceScaleFactor=1, mobile=False)
                        await browser.open(url, until)
                        await browser.js(UNFOLD)
                        await browser.shoot(HERE / name, width, height)
        finally:
            proc.terminate()
            proc.wait(timeout=30)


def main(argv: list[str]) -> int:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None or len(argv) != 1:
        print(__doc__ if chromium else "chromium not found", file=sys.stderr)
        return 2
    uri = f"sqlite:///{Path(argv[0]).resolve()}/mlflow.db"
    from maglev.study.store import find_parent, open_store
    from maglev.study.tracking import run_link

    client, exp_id = open_store(uri, "maglev")
    ranking = client.get_run(find_parent(client, exp_id).data.tags["ranking_run"])
    best = client.get_run(ranking.data.tags["best_run"])
    proc, url = start_ui(uri, free_port())
    base = url.split("/#/")[0]
    try:
        asyncio.run(shoot_all(chromium, base, [
            ("runs.png", url, best.info.run_name, 1800, 800),
            ("model_run.png", f"{base}/{run_link(exp_id, best.info.run_id)}", "Description", 1250, 1180),
            ("ranking_run.png", f"{base}/{run_link(exp_id, ranking.info.run_id)}", "Description", 1250, 1330)]))
    finally:
        proc.send_signal(signal.SIGINT)  # maglev ui stops its server
        proc.wait(timeout=30)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
