"""stageid serve, server side: every board action through an HTTP client, and the robustness
rules (one-line errors, path traversal, upload size, cancel, separate sessions, token)."""

import contextlib
import io
import shlex
import subprocess
import sys
import time
import urllib.error
import urllib.request
import zipfile

import numpy as np
import pytest

pytest.importorskip("starlette")
from starlette.testclient import TestClient  # noqa: E402

from stageid.app.server import create_app  # noqa: E402
from stageid.cli.main import main as cli_main  # noqa: E402
from stageid.data.io import write_csv  # noqa: E402

DT = 1e-3


def _record(seed: int, n: int = 3000) -> dict[str, np.ndarray]:
    """A lightly damped second-order stage (poles 0.95 +- 0.2j) driven by white noise."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = np.zeros(n)
    for k in range(2, n):
        y[k] = 1.9 * y[k - 1] - 0.9425 * y[k - 2] + 0.05 * u[k - 1] + 0.03 * u[k - 2]
    return {"u": u, "y": y + 1e-3 * rng.standard_normal(n) + 0.5}


@pytest.fixture
def folder(tmp_path):
    records = tmp_path / "records"
    records.mkdir()
    write_csv(records / "run.csv", _record(0), dt=DT)
    write_csv(records / "held_out.csv", _record(1), dt=DT)
    (tmp_path / "secret.csv").write_text("t,u\n0,1\n0.001,2\n")
    return records


@pytest.fixture
def client(folder, tmp_path):
    with TestClient(create_app(folder, tmp_path / "scratch")) as c:
        yield c


def wait(client, job, timeout=120.0):
    """Poll a job until it leaves ``running``; returns its final state."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        state = client.get(f"/api/jobs/{job['id']}").json()
        if state["status"] != "running":
            return state
        time.sleep(0.1)
    raise AssertionError(f"job {job['id']} still running after {timeout} s")


def prepare(client, name="run.csv", **settings):
    settings = {"inputs": ["u"], "outputs": ["y"], "detrend": "constant"} | settings
    response = client.post("/api/prepare", json={"source": "folder", "name": name, "settings": settings})
    assert response.status_code == 200, response.text
    return response.json()


def reproduce(client, tmp_path, job_state, files):
    """Run the command the page showed (in process), on downloaded copies of its inputs, in a fresh folder."""
    work = tmp_path / f"cli-{job_state['id']}"
    work.mkdir()
    for name in files:
        (work / name).write_bytes(client.get(f"/api/files/{name}").content)
    args = shlex.split(job_state["cli"])
    assert args[0] == "stageid"
    with contextlib.chdir(work):
        assert cli_main(args[1:]) == 0
    return work


def test_state_lists_the_folders_records(client):
    state = client.get("/api/state").json()
    assert state["records"] == ["held_out.csv", "run.csv"]
    assert state["datasets"] == {} and state["models"] == {}


def test_data_board_trims_detrends_and_plots(client):
    info = client.get("/api/inspect", params={"source": "folder", "name": "run.csv"}).json()
    assert info["kind"] == "time" and info["columns"] == ["u", "y"] and info["n_samples"] == 3000
    d = prepare(client, start=0.5, stop=2.5)
    assert d["n_samples"] == 2000 and d["inputs"] == ["u"] and d["outputs"] == ["y"]
    assert d["figures"]["time"].lstrip().startswith("<?xml") and "<svg" in d["figures"]["spectrum"]
    assert "exp.slice(500, 2500)" in d["python"] and "remove_offset(exp, 'constant')" in d["python"]
    data = np.load(io.BytesIO(client.get(f"/api/files/{d['file']}").content))
    assert abs(float(np.mean(data["y"]))) < 1e-9  # the constant offset of 0.5 is gone
    decimated = prepare(client, decimate=4)
    assert decimated["n_samples"] == 750 and decimated["dt"] == pytest.approx(4 * DT)
    assert "decimate(exp, 4)" in decimated["python"]


def test_frf_estimate_is_the_cli_output_byte_for_byte(client, tmp_path):
    d = prepare(client)
    job = client.post("/api/estimate", json={"method": "frf", "data": d["name"], "options": {"segment": "512"}}).json()
    assert job["cli"].startswith("stageid frf d") and "--segment 512" in job["cli"]
    state = wait(client, job)
    assert state["status"] == "done", state["error"]
    frd = state["result"]["dataset"]
    assert frd["kind"] == "frd" and "<svg" in state["result"]["figures"]["bode"]
    work = reproduce(client, tmp_path, state, [d["file"]])
    assert (work / frd["file"]).read_bytes() == client.get(f"/api/files/{frd['file']}").content
    (work / frd["file"]).unlink()
    with contextlib.chdir(work):
        exec(state["python"], {})  # the Python shown beside the command
    assert (work / frd["file"]).read_bytes() == client.get(f"/api/files/{frd['file']}").content


def test_statespace_singular_values_show_the_order(client):
    d = prepare(client)
    state = wait(client, client.post("/api/order", json={"data": d["name"], "options": {"horizon": "12"}}).json())
    assert state["status"] == "done", state["error"]
    s = np.array(state["result"]["singular_values"])
    assert s[1] > 30 * s[2]  # a second-order stage: the gap after two singular values
    assert "<svg" in state["result"]["figures"]["singular_values"]


def test_estimate_compare_and_export_equal_the_cli(client, tmp_path):
    d = prepare(client)
    options = {"order": "2", "horizon": "10"}
    state = wait(
        client,
        client.post("/api/estimate", json={"method": "statespace", "data": d["name"], "options": options}).json(),
    )
    assert state["status"] == "done", state["error"]
    model = state["result"]["model"]["name"]
    assert "HankelMAP(horizon=10, order=2)" in state["python"]
    assert "<svg" in state["result"]["figures"]["bands"]  # the response with its +-2 std band
    work = reproduce(client, tmp_path, state, [d["file"]])
    exported = wait(client, client.post("/api/export", json={"model": model, "format": "json"}).json())
    assert (work / f"{model}.json").read_bytes() == client.get(exported["result"]["download"]).content
    # the Python shown beside the command writes the same model file
    (work / f"{model}.json").unlink()
    with contextlib.chdir(work):
        exec(state["python"], {})
    assert (work / f"{model}.json").read_bytes() == client.get(exported["result"]["download"]).content

    held = prepare(client, "held_out.csv")
    state = wait(client, client.post("/api/compare", json={"model": model, "data": held["name"]}).json())
    assert state["status"] == "done", state["error"]
    assert state["result"]["validation"]["outputs"]["y"]["fit_percent"] > 90
    assert {"overlay", "bands", "residuals y"} <= set(state["result"]["figures"])

    mat = wait(client, client.post("/api/export", json={"model": model, "format": "mat"}).json())
    cli_mat = reproduce(client, tmp_path, mat, [f"{model}.json"]) / f"{model}.mat"
    # bytes 0-115 are MATLAB's header text with the creation time; everything after must agree
    assert cli_mat.read_bytes()[116:] == client.get(mat["result"]["download"]).content[116:]
    c = wait(
        client, client.post("/api/export", json={"model": model, "format": "c", "options": {"prefix": "stage"}}).json()
    )
    archive = zipfile.ZipFile(io.BytesIO(client.get(c["result"]["download"]).content))
    assert sorted(archive.namelist()) == ["stage.c", "stage.h"]
    cli_c = reproduce(client, tmp_path, c, [f"{model}.json"]) / f"{model}_c"
    assert archive.read("stage.c") == (cli_c / "stage.c").read_bytes()


def test_bad_option_shows_the_cli_message_and_the_server_goes_on(client, tmp_path, capsys):
    d = prepare(client)
    state = wait(
        client,
        client.post(
            "/api/estimate", json={"method": "statespace", "data": d["name"], "options": {"order": "x2"}}
        ).json(),
    )
    assert state["status"] == "failed"
    data = tmp_path / "d.npz"
    data.write_bytes(client.get(f"/api/files/{d['file']}").content)
    code = cli_main(
        [
            "identify",
            "statespace",
            str(data),
            "--inputs",
            "u",
            "--outputs",
            "y",
            "--order",
            "x2",
            "-o",
            str(tmp_path / "m.json"),
        ]
    )
    assert code == 2
    assert state["error"] == capsys.readouterr().err.strip()
    assert client.get("/api/state").status_code == 200


def test_malformed_upload_is_refused_in_one_line_and_not_kept(client):
    response = client.post("/api/upload", params={"name": "broken.csv"}, content=b"t,u,y\n0,1\n0.001,abc,2\n")
    assert response.status_code == 400
    error = response.json()["error"]
    assert error.startswith("stageid: error: ") and "\n" not in error
    assert client.get("/api/state").json()["uploads"] == []


@pytest.mark.parametrize(
    "name, content",
    [
        ("garbage.npz", b"PK\x03\x04 not really a zip archive"),
        ("garbage.mat", b"MATLAB 5.0 MAT-file" + bytes(200)),
        ("garbage.h5", b"\x89HDF\r\n\x1a\n" + bytes(64)),
        ("empty.csv", b""),
        ("binary.csv", bytes(range(256)) * 4),
    ],
)
def test_malformed_files_of_every_format_are_refused(client, name, content):
    response = client.post("/api/upload", params={"name": name}, content=content)
    assert response.status_code == 400, response.text
    assert response.json()["error"].startswith("stageid: error: ")
    assert client.get("/api/state").json()["uploads"] == []


def test_cancelled_singular_values_are_dropped(client):
    d = prepare(client)
    job = client.post("/api/order", json={"data": d["name"], "options": {"horizon": "12"}}).json()
    assert client.post(f"/api/jobs/{job['id']}/cancel").json()["status"] == "cancelled"
    time.sleep(0.5)
    assert client.get(f"/api/jobs/{job['id']}").json()["result"] == {}


def test_good_upload_can_be_opened(client, folder):
    response = client.post("/api/upload", params={"name": "mine.csv"}, content=(folder / "run.csv").read_bytes())
    assert response.status_code == 200 and response.json()["columns"] == ["u", "y"]
    assert client.get("/api/state").json()["uploads"] == ["mine.csv"]
    d = client.post(
        "/api/prepare", json={"source": "upload", "name": "mine.csv", "settings": {"inputs": ["u"], "outputs": ["y"]}}
    )
    assert d.status_code == 200


@pytest.mark.parametrize("name", ["../secret.csv", "a/../../secret.csv", "/etc/passwd", ".."])
def test_record_names_cannot_leave_the_folder(client, name):
    response = client.get("/api/inspect", params={"source": "folder", "name": name})
    assert response.status_code == 400 and "outside the served folder" in response.json()["error"]


def test_symbolic_link_out_of_the_folder_is_refused(client, folder):
    (folder / "link.csv").symlink_to(folder.parent / "secret.csv")
    response = client.get("/api/inspect", params={"source": "folder", "name": "link.csv"})
    assert response.status_code == 400 and "outside the served folder" in response.json()["error"]


@pytest.mark.parametrize("name", ["../evil.csv", "sub/evil.csv", "..csv", "evil.sh", ""])
def test_upload_names_are_plain_file_names(client, name):
    response = client.post("/api/upload", params={"name": name}, content=b"t,u\n0,1\n")
    assert response.status_code == 400, response.text
    assert client.get("/api/state").json()["uploads"] == []


def test_oversize_upload_is_refused(folder, tmp_path):
    with TestClient(create_app(folder, tmp_path / "scratch", max_upload_mb=0.01)) as small:
        response = small.post("/api/upload", params={"name": "big.csv"}, content=b"0" * 20_000)
        assert response.status_code == 413 and "0.01 MB limit" in response.json()["error"]
        # without a declared length (chunked), the limit is counted while the body arrives
        chunked = small.post("/api/upload", params={"name": "big.csv"}, content=iter([b"0" * 8000] * 3))
        assert chunked.status_code == 413 and "0.01 MB limit" in chunked.json()["error"]
        assert small.get("/api/state").json()["uploads"] == []
        assert not any(small.app.state.sessions.root.rglob("*big*"))  # no partial file left behind


def test_cancelled_fit_ends_without_a_model(client):
    d = prepare(client)
    job = client.post("/api/estimate", json={"method": "statespace", "data": d["name"], "options": {}}).json()
    assert job["status"] == "running"
    client.post(f"/api/jobs/{job['id']}/cancel")
    state = wait(client, job, timeout=20)
    assert state["status"] == "cancelled"
    assert client.get("/api/state").json()["models"] == {}


def test_two_sessions_do_not_share_state(folder, tmp_path):
    app = create_app(folder, tmp_path / "scratch")
    with TestClient(app) as first, TestClient(app) as second:
        d = prepare(first)
        assert list(first.get("/api/state").json()["datasets"]) == [d["name"]]
        assert second.get("/api/state").json()["datasets"] == {}
        assert second.get(f"/api/files/{d['file']}").status_code == 400
        assert first.cookies["stageid_session"] != second.cookies["stageid_session"]


def test_two_tabs_of_one_browser_are_two_sessions(client):
    """Tabs share cookies; the page sends its tab's key in a header instead."""
    keys = [client.get("/api/state", headers={"X-Stageid-Session": ""}).headers["x-stageid-session"] for _ in range(2)]
    assert keys[0] != keys[1]
    settings = {"inputs": ["u"], "outputs": ["y"]}
    made = client.post(
        "/api/prepare",
        json={"source": "folder", "name": "run.csv", "settings": settings},
        headers={"X-Stageid-Session": keys[0]},
    ).json()
    assert list(client.get("/api/state", headers={"X-Stageid-Session": keys[0]}).json()["datasets"]) == [made["name"]]
    assert client.get("/api/state", headers={"X-Stageid-Session": keys[1]}).json()["datasets"] == {}
    assert client.get("/api/state").json()["datasets"] == {}  # the cookie's session is a third one
    assert client.get(f"/api/files/{made['file']}", params={"session": keys[0]}).status_code == 200
    assert client.get(f"/api/files/{made['file']}", params={"session": keys[1]}).status_code == 400


def test_token_is_required_when_asked(folder, tmp_path):
    with TestClient(create_app(folder, tmp_path / "scratch", token="s3cret")) as c:
        assert c.get("/").status_code == 403
        assert c.get("/api/state", params={"token": "wrong"}).status_code == 403
        assert c.get("/", params={"token": "s3cret"}).status_code == 200
        assert c.get("/api/state").status_code == 200  # the token is now a cookie


def test_page_loads_nothing_from_the_network(client):
    page = client.get("/").text
    for asset in ("/static/app.js", "/static/app.css"):
        assert asset in page
        assert client.get(asset).status_code == 200
    for text in (page, client.get("/static/app.js").text, client.get("/static/app.css").text):
        assert "http://" not in text and "https://" not in text


def _serve(args, cwd):
    process = subprocess.Popen(
        [sys.executable, "-m", "stageid", "serve", *args], cwd=cwd, stdout=subprocess.PIPE, text=True
    )
    return process, process.stdout.readline().split()[2]


def _status(url):
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return response.status
    except urllib.error.HTTPError as error:
        return error.code


@pytest.mark.parametrize("host", ["127.0.0.1", "0.0.0.0"])
def test_serve_command_prints_its_address(folder, host):
    process, address = _serve([str(folder), "--port", "0", "--host", host], folder)
    try:
        assert address.startswith(f"http://{host}:")
        plain = address.split("?")[0].replace("0.0.0.0", "127.0.0.1")
        if host == "127.0.0.1":
            assert "token" not in address and _status(plain) == 200
        else:
            assert "?token=" in address and _status(plain) == 403
            assert _status(address.replace("0.0.0.0", "127.0.0.1")) == 200
    finally:
        process.terminate()
        process.wait(timeout=10)


def test_records_without_time_column_and_frf_tables(client, folder):
    write_csv(folder / "no_t.csv", _record(2, 200))
    response = client.get("/api/inspect", params={"source": "folder", "name": "no_t.csv"})
    assert response.status_code == 400 and "no time column" in response.json()["error"]
    info = client.get("/api/inspect", params={"source": "folder", "name": "no_t.csv", "ts": "0.001"}).json()
    assert info["kind"] == "time" and info["dt"] == 0.001

    f = np.linspace(1.0, 100.0, 50)
    g = 1.0 / (1.0 + 1j * f / 20.0)
    write_csv(folder / "frf.csv", {"f_hz": f, "re_y_u": g.real, "im_y_u": g.imag})
    info = client.get("/api/inspect", params={"source": "folder", "name": "frf.csv"}).json()
    assert info["kind"] == "frd" and info["responses"]["response"]["n_freqs"] == 50
    d = client.post("/api/prepare", json={"source": "folder", "name": "frf.csv", "settings": {"fmax": 50.0}}).json()
    assert d["kind"] == "frd" and d["band"][1] <= 50.0 and d["inputs"] == ["u"] and "<svg" in d["figures"]["bode"]


def test_mat_frf_struct_is_read_as_the_command_line_reads_it(client, folder, tmp_path):
    """One reader: the board lists a MATLAB FRF file's responses by the names ``identify frd
    --response`` takes, with the same values, a rad/s axis included."""
    import scipy.io

    from stageid.models.frequency_response import read_frd

    w = 2 * np.pi * np.geomspace(1.0, 200.0, 40)
    g = 3.0 / (1.0 + 1j * w / 300.0)
    scipy.io.savemat(folder / "frf.mat", {"meas": {"w_s": w, "G_V2z": g, "G_V2x": 0.5 * g, "notes": "bench 2"}})
    info = client.get("/api/inspect", params={"source": "folder", "name": "frf.mat"}).json()
    assert info["kind"] == "frd" and sorted(info["responses"]) == ["G_V2x", "G_V2z"]
    assert info["responses"]["G_V2z"]["inputs"] == ["V"] and info["responses"]["G_V2z"]["outputs"] == ["z"]
    settings = {"response": "G_V2z", "fmax": 100.0}
    d = client.post("/api/prepare", json={"source": "folder", "name": "frf.mat", "settings": settings}).json()
    assert d["kind"] == "frd" and d["outputs"] == ["z"] and d["band"][1] <= 100.0
    cli = read_frd(folder / "frf.mat", "G_V2z").band(None, 100.0)
    (written,) = (tmp_path / "scratch").rglob(d["file"])
    board = read_frd(written)
    assert np.allclose(board.freqs, cli.freqs, rtol=1e-12) and np.allclose(board.response, cli.response, rtol=1e-12)
    assert np.isclose(board.freqs[0], 1.0, rtol=1e-9)  # w_s [rad/s] read as Hz / (2 pi)


def test_hysteresis_estimate_draws_its_loops(client, folder):
    subprocess.run(
        [sys.executable, "-m", "stageid", "plants", "piezo-actuator", "--experiment", "triangle-1hz", "-o", "tri.csv"],
        cwd=folder,
        check=True,
        capture_output=True,
    )
    d = prepare(client, "tri.csv", inputs=["V"], outputs=["y"], detrend="none", stop=1.0)
    job = client.post("/api/estimate", json={"method": "hysteresis", "data": d["name"], "options": {"model": "pi"}})
    state = wait(client, job.json())
    assert state["status"] == "done", state["error"]
    assert state["cli"].endswith("--input V --output y --model pi -o " + state["result"]["model"]["name"] + ".json")
    assert "pi model" in state["result"]["model"]["summary"] and "<svg" in state["result"]["figures"]["loops"]
    two = prepare(client, "run.csv", inputs=["u"], outputs=["y"])
    refused = client.post("/api/estimate", json={"method": "frd", "data": two["name"], "options": {}})
    assert refused.status_code == 400 and "needs a frequency response" in refused.json()["error"]


@pytest.mark.slow  # four reference-stage records and a 3x3 closed-loop fit (tests/TIMING.md)
def test_closed_loop_plant_from_one_data_set_per_reference(client, folder):
    for args in (
        ["--controller", "-o", "K.json"],
        *(["--experiment", f"chirp-{a}", "-o", f"cl_{a}.csv"] for a in ("x", "y", "phi")),
    ):
        with contextlib.chdir(folder):
            assert cli_main(["plants", "maglev", *args]) == 0
    assert client.get("/api/state").json()["model_files"] == ["K.json"]
    channels = {"inputs": ["r_x", "r_y", "r_phi"], "outputs": ["x", "y", "phi"], "detrend": "none", "stop": 4.0}
    names = [prepare(client, f"cl_{a}.csv", **channels)["name"] for a in ("x", "y", "phi")]
    options = {"controller": "K.json"}
    job = client.post("/api/estimate", json={"method": "closedloop", "data": ",".join(names), "options": options})
    # the fit alone is tens of seconds of CPU: the guard against a hung job leaves room for a busy machine
    state = wait(client, job.json(), timeout=600.0)
    assert state["status"] == "done", state["error"]
    assert "--references r_x,r_y,r_phi --outputs x,y,phi --controller K_K.json" in state["cli"]
    assert state["result"]["model"]["inputs"] == ["Fx", "Fy", "Tphi"] and "<svg" in state["result"]["figures"]["bode"]
    refused = client.post(
        "/api/estimate", json={"method": "closedloop", "data": names[0], "options": {"controller": "../K.json"}}
    )
    assert refused.status_code == 400 and "outside the served folder" in refused.json()["error"]


def test_closed_loop_with_the_controller_unknown_runs_the_direct_route(client, folder):
    from stageid.plants import levitated_pair

    _, u, y = levitated_pair.record(2000, seed=0)
    t = np.arange(len(u)) * levitated_pair.DT
    write_csv(folder / "loop.csv", {"t": t, "u1": u[:, 0], "u2": u[:, 1], "y1": y[:, 0], "y2": y[:, 1]})
    d = prepare(client, "loop.csv", inputs=["u1", "u2"], outputs=["y1", "y2"], detrend="none")
    options = {"controller": "unknown", "order": "4"}
    job = client.post("/api/estimate", json={"method": "closedloop", "data": d["name"], "options": options})
    state = wait(client, job.json())
    assert state["status"] == "done", state["error"]
    assert "--plant-inputs u1,u2 --outputs y1,y2 --controller unknown --method direct --order 4 -o" in state["cli"]
    assert "DirectPredictionError(order=4).fit(exps)" in state["python"]
    assert state["result"]["model"]["inputs"] == ["u1", "u2"] and "<svg" in state["result"]["figures"]["bode"]
    # the levitated pair's unstable poles are 31.4 and 50 rad/s (the fit is told neither nor the controller)
    line = next(x for x in state["result"]["model"]["summary"].splitlines() if "unstable poles" in x)
    found = [float(v.split("+-")[0]) for v in line.split(":", 1)[1].split(",")]
    assert np.allclose(sorted(found), [31.4, 50.0], rtol=0.02), line


def test_hysteresis_loops_of_a_long_fast_record_show_the_last_cycles(client, folder):
    t = np.arange(2000) * 1e-3
    u = 5.0 * np.sin(2 * np.pi * 20.0 * t)  # 40 cycles: drawn whole they are a solid block
    y = 0.8 * u + 0.3 * np.abs(u) * np.sign(np.gradient(u))
    write_csv(folder / "fast.csv", {"t": t, "V": u, "y": y})
    d = prepare(client, "fast.csv", inputs=["V"], outputs=["y"], detrend="none")
    job = client.post("/api/estimate", json={"method": "hysteresis", "data": d["name"], "options": {"model": "pi"}})
    state = wait(client, job.json())
    assert state["status"] == "done", state["error"]
    loops = state["result"]["figures"]["loops"]
    # three panels: the last cycles' loops, their error, the whole record's error envelope
    assert 'id="axes_3"' in loops and 'id="axes_4"' not in loops


def test_the_frd_fit_python_uses_the_fit_s_parameter_names():
    import warnings

    from stageid.app.estimate import _frd_settings
    from stageid.frf import FRDIdentification

    text = _frd_settings({"order": "6", "dt": "4e-05", "fmin": "", "fmax": "2000", "delay": "auto"})
    assert text == "order=6, sample_time=4e-05, band=(None, 2000), delay='auto'"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no former name in the code the board shows
        est = eval(f"FRDIdentification({text})", {"FRDIdentification": FRDIdentification})
    assert est.band == (None, 2000) and est.sample_time == 4e-05
