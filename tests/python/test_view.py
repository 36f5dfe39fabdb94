"""spacewarp.view: the viewer's server on a background thread, spoken to over HTTP (urllib)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from conftest import CUBE, CUBE_QUADS

spacewarp = pytest.importorskip("spacewarp")
if not hasattr(spacewarp, "view"):
    pytest.skip("built without the command-line tool (no spacewarp.view)", allow_module_level=True)


@pytest.fixture
def scene(tmp_path: Path) -> dict:
    """A cube cage around a random cloud, a page folder and a save folder."""
    cage = tmp_path / "cage.obj"
    spacewarp.write(cage, spacewarp.Geometry(CUBE, faces=CUBE_QUADS))
    points = np.random.default_rng(5).uniform(-0.8, 0.8, (500, 3))
    model = tmp_path / "cloud.ply"
    spacewarp.write(model, spacewarp.Geometry(points))
    page = tmp_path / "page"
    page.mkdir()
    (page / "index.html").write_text("<html>viewer</html>")
    saves = tmp_path / "saves"
    saves.mkdir()
    return {"cage": cage, "model": model, "points": points, "page": page, "saves": saves}


def _get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=60) as response:
        return response.read()


def _post(url: str, body: bytes, kind: str) -> bytes:
    request = urllib.request.Request(url, data=body, method="POST", headers={"Content-Type": kind})
    with urllib.request.urlopen(request, timeout=60) as response:
        return response.read()


def test_pose_positions_are_the_deform_of_the_saved_rig(scene):
    with spacewarp.view(scene["model"], cage=scene["cage"], method="green",
                        save_dir=scene["saves"], web_dir=scene["page"]) as viewer:
        assert viewer.url.startswith("http://127.0.0.1:") and viewer.url.endswith("/")
        described = json.loads(_get(viewer.url + "api/scene"))
        assert described["method"] == "green"
        assert described["model"]["vertexCount"] == 500
        assert described["model"]["kind"] == "cloud"
        rest = np.array(described["controls"]["rest"])
        assert rest.shape == (8, 3)
        pose = rest * [1.2, 1.0, 0.9] + [0.1, 0.0, 0.2]
        pose[7] += [0.3, 0.2, 0.1]
        answer = _post(viewer.url + "api/pose", pose.astype("<f8").tobytes(),
                       "application/octet-stream")
        positions = np.frombuffer(answer, dtype="<f4").reshape(-1, 3)
        saved = json.loads(_post(viewer.url + "api/save", b'{"what": "rig"}', "application/json"))
        rig = Path(saved["paths"][-1])
        assert rig == scene["saves"] / "cloud_rig.json"
        expected = spacewarp.load_rig(rig)(scene["points"])
        # The answer is float32 offsets from the scene's origin (the cloud's bounding-box centre).
        origin = np.array(described["origin"])
        lo, hi = scene["points"].min(axis=0), scene["points"].max(axis=0)
        np.testing.assert_array_equal(origin, (lo + hi) / 2)
        np.testing.assert_allclose(positions, (expected - origin).astype(np.float32), rtol=0,
                                   atol=1e-6)
        assert np.abs(expected - scene["points"]).max() > 0.05  # the pose moved the cloud
        assert _get(viewer.url) == b"<html>viewer</html>"
    with pytest.raises(urllib.error.URLError):  # stopped on leaving the block
        _get(viewer.url + "api/scene")


def test_stop_is_idempotent_and_errors_are_typed(scene):
    viewer = spacewarp.view(scene["model"], cage=scene["cage"], web_dir=scene["page"])
    viewer.stop()
    viewer.stop()
    with pytest.raises(spacewarp.InvalidInput):
        spacewarp.view(scene["model"], web_dir=scene["page"])  # neither cage nor rig
    with pytest.raises(spacewarp.IoError, match="nodejs npm"):
        spacewarp.view(scene["model"], cage=scene["cage"], web_dir=scene["saves"])
    with pytest.raises(spacewarp.IoError, match="missing.obj"):
        spacewarp.view(scene["model"].parent / "missing.obj", cage=scene["cage"],
                       web_dir=scene["page"])


def test_bad_arguments_are_refused_before_serving(scene):
    with pytest.raises(spacewarp.InvalidInput, match="port"):
        spacewarp.view(scene["model"], cage=scene["cage"], port=70000, web_dir=scene["page"])
    missing = scene["saves"] / "missing"
    with pytest.raises(spacewarp.IoError, match="save_dir .*missing: not a folder"):
        spacewarp.view(scene["model"], cage=scene["cage"], save_dir=missing, web_dir=scene["page"])
    with pytest.raises(spacewarp.InvalidInput, match="method"):
        spacewarp.view(scene["model"], cage=scene["cage"], method="nope", web_dir=scene["page"])


def test_a_second_viewer_on_a_taken_port_fails_and_a_collected_one_frees_it(scene):
    import gc

    first = spacewarp.view(scene["model"], cage=scene["cage"], web_dir=scene["page"])
    port = first.port
    with pytest.raises(RuntimeError, match=str(port)):
        spacewarp.view(scene["model"], cage=scene["cage"], port=port, web_dir=scene["page"])
    assert json.loads(_get(first.url + "api/scene"))["model"]["vertexCount"] == 500
    # Dropped without stop(): the collector stops it and the port can be taken again.
    del first
    gc.collect()
    with spacewarp.view(scene["model"], cage=scene["cage"], port=port,
                        web_dir=scene["page"]) as again:
        assert again.port == port
        assert json.loads(_get(again.url + "api/scene"))["method"] == "mvc"
