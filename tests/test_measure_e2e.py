"""End to end in a real headless Chromium: the loop analysis' *Measure* button measures the loop on
the test stand at the present gains and draws the measured Bode plot over the predicted one.
Skips without /usr/bin/chromium, except under CI=true."""

from __future__ import annotations

import base64
import io
import re
from pathlib import Path

import numpy as np
from hopper.app.dashboard.server import Dashboard
from PIL import Image
from test_dashboard_e2e import open_workbench

MEASURED_JS = "() => document.querySelector('.hd-measured') ? document.querySelector('.hd-measured').innerText : ''"
# viser shows a GUI image from a blob URL: read its bytes back (base64) from the page itself.
BODE_JS = """async () => {
  const blobs = [...document.querySelectorAll('img')].filter(i => i.src.startsWith('blob:') && i.naturalWidth > 300);
  if (!blobs.length) return '';
  const bytes = new Uint8Array(await (await fetch(blobs[0].src)).arrayBuffer());
  let text = ''; for (const b of bytes) text += String.fromCharCode(b);
  return btoa(text);
}"""


def test_measure_draws_the_measured_loop_over_the_model(browser, dashboard: Dashboard, tmp_path: Path):  # noqa: F811
    dashboard.layout.simulation.set_paused(True)
    page = open_workbench(browser, dashboard)
    try:
        page.get_by_role("button", name="Measure").click()
        page.wait_for_function(f"() => ({MEASURED_JS})().includes('coherence at the crossover')", timeout=120_000)
        text = page.evaluate(MEASURED_JS)
        assert "stand (legs locked), PaperPID" in text
        row = re.search(r"crossover Hz\s+([\d.]+)\s+([\d.]+)", text.replace("\u00a0", " "))
        assert row, text
        measured, predicted = float(row.group(1)), float(row.group(2))
        assert abs(measured / predicted - 1.0) < 0.05, (measured, predicted)
        # The Bode plot reached the page: an image of the measured points over the model's curve.
        page.wait_for_function(
            "() => [...document.querySelectorAll('img')].some(i => i.src.startsWith('blob:') && i.naturalWidth > 300)",
            timeout=60_000,
        )
        png = base64.b64decode(page.evaluate(BODE_JS))
        image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
        assert image.shape[0] > 300 and image.shape[1] > 400
        pixels = image.reshape(-1, 3).astype(int)
        for name, rgb in (("measured (blue)", (31, 111, 180)), ("predicted (orange)", (224, 137, 43))):
            near = np.abs(pixels - np.array(rgb)).max(axis=1) < 40
            assert near.sum() > 500, f"too few {name} pixels in the Bode plot: {near.sum()}"
        (tmp_path / "bode.png").write_bytes(png)
        page.screenshot(path=str(tmp_path / "page.png"))
        print("bode", tmp_path / "bode.png", "page", tmp_path / "page.png")
    finally:
        page.close()
