"""The DEM campaign: resumable (a killed campaign rerun ends with the same files as an
uninterrupted one, and calibrates to the same parameters), and bad input refused."""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contfab.calibration.calibrate import calibrate
from contfab.calibration.campaign import CampaignError, CampaignSettings, Layout, RunSpec, run_campaign
from contfab.executor import make_executor
from contfab.params import load_params
from dem.checkpoint import load as load_checkpoint
from dem.paths import PathError

ROOT = Path(__file__).resolve().parent.parent
LONG = """name = "long_biaxial"
[[stage]]
name = "compress"
length = 0.2
output_every = 0.005
L = { yy = -1.0, xy = 0.0, yx = 0.0 }
sigma = { xx = -1.0 }
"""
SCRIPT = """
import sys
from contfab.calibration.campaign import CampaignSettings, RunSpec, run_campaign
from contfab.executor import make_executor
cs = CampaignSettings(n=40, seeds=(1,), runs=(RunSpec(sys.argv[2], "dense", 1e3),), probe=False,
                      checkpoint_every=2)
run_campaign(cs, sys.argv[1], make_executor("serial"))
"""


def settings(path_file):
    return CampaignSettings(n=40, seeds=(1,), runs=(RunSpec(str(path_file), "dense", 1e3),),
                            probe=False, checkpoint_every=2)


def test_killed_campaign_resumes_to_the_same_history_and_parameters(tmp_path):
    path_file = tmp_path / "long_biaxial.toml"
    path_file.write_text(LONG)
    cs = settings(path_file)
    with make_executor("serial") as ex:
        run_campaign(cs, tmp_path / "a", ex)
    run_b = Layout(tmp_path / "b").run(cs.runs[0].name, 1)
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(tmp_path / "b"), str(path_file)],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 300
        while not (run_b / "checkpoint.npz").exists() and proc.poll() is None:
            assert time.time() < deadline, "no checkpoint within 300 s"
            time.sleep(0.02)
    finally:
        proc.kill()
        proc.wait()
    assert not (run_b / "history.json").exists(), "the run finished before it could be killed"
    assert (run_b / "checkpoint.npz").exists(), proc.stderr.read().decode()[-2000:]
    rows_at_kill = len(load_checkpoint(run_b / "checkpoint.npz")[2].rows)
    assert 1 < rows_at_kill < 41
    with make_executor("serial") as ex:
        run_campaign(cs, tmp_path / "b", ex)                      # resumes from the checkpoint
    run_a = Layout(tmp_path / "a").run(cs.runs[0].name, 1)
    assert (run_a / "history.csv").read_bytes() == (run_b / "history.csv").read_bytes()
    assert json.loads((run_b / "history.json").read_text())["resumed_from"].endswith("checkpoint.npz")
    # the calibration (tier 1) of both campaigns: the same parameters
    fitted = [load_params(calibrate(tmp_path / d, 1, cs, progress=False)["params"]).to_dict()
              for d in ("a", "b")]
    assert fitted[0] == fitted[1]


def test_runs_of_other_settings_are_refused_in_a_campaign_directory(tmp_path):
    path_file = tmp_path / "short.toml"
    path_file.write_text(LONG.replace("length = 0.2", "length = 0.01"))
    cs = settings(path_file)
    with make_executor("serial") as ex:
        run_campaign(cs, tmp_path / "c", ex)
        other = CampaignSettings(n=41, seeds=(1,), runs=cs.runs, probe=False)
        with pytest.raises(CampaignError, match="results of a different job"):
            run_campaign(other, tmp_path / "c", ex)
        job = Layout(tmp_path / "c").run(cs.runs[0].name, 1) / "job.json"
        job.write_text(job.read_text().replace('"n": 40', '"n": 39'))
        (tmp_path / "c" / "dem" / "prepared" / "dense_k1000_seed1.npz").unlink()
        with pytest.raises(CampaignError, match="results of a different job"):
            run_campaign(cs, tmp_path / "c", ex)


def test_a_copied_campaign_directory_is_reused_not_refused(tmp_path):
    """Job records name their start checkpoint relative to themselves: a campaign directory
    copied elsewhere resumes there with nothing rerun (it was refused: absolute paths)."""
    import shutil

    path_file = tmp_path / "short.toml"
    path_file.write_text(LONG.replace("length = 0.2", "length = 0.01"))
    cs = settings(path_file)
    with make_executor("serial") as ex:
        run_campaign(cs, tmp_path / "here", ex)
        shutil.copytree(tmp_path / "here", tmp_path / "there")
        shutil.rmtree(tmp_path / "here")
        history = Layout(tmp_path / "there").run(cs.runs[0].name, 1) / "history.csv"
        stamp = history.stat().st_mtime_ns
        run_campaign(cs, tmp_path / "there", ex)
    assert history.stat().st_mtime_ns == stamp
    job = json.loads((history.parent / "job.json").read_text())
    assert not os.path.isabs(job["start"]) and job["start"].endswith("dense_k1000_seed1.npz")


@pytest.mark.parametrize("change, error, words", [
    (dict(runs=(RunSpec("no_such_path", "dense", 1e3),)), PathError, "unknown loading path 'no_such_path'"),
    (dict(runs=(RunSpec("biaxial", "medium", 1e3),)), CampaignError, "density 'medium'"),
    (dict(runs=(RunSpec("biaxial", "dense", -1.0),)), CampaignError, "kappa = -1.0 out of range"),
    (dict(runs=(RunSpec("biaxial", "dense", 1e3, "heldout"),)), CampaignError, "role 'fit'"),
    (dict(seeds=()), CampaignError, "one or more distinct seeds"),
    (dict(n=1), ValueError, "n = 1 out of range"),
    (dict(probe_magnitude=0.0), CampaignError, "probe_magnitude = 0.0 out of range"),
])
def test_bad_campaign_settings_are_refused_before_anything_runs(tmp_path, change, error, words):
    cs = CampaignSettings(**change)
    with pytest.raises(error, match=words):
        with make_executor("serial") as ex:
            run_campaign(cs, tmp_path / "x", ex)
    assert not (tmp_path / "x").exists()
