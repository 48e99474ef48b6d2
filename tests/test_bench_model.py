"""`contfab bench model`: its figures exist, are positive, and measure plastic updates."""
import json
from types import SimpleNamespace

from contfab.bench import model
from contfab.cli import main


def test_bench_model_figures_at_a_yielding_state():
    figures = model.run(SimpleNamespace(repeats=1, points=2000))
    for tier in model.BENCH_TIERS:
        assert figures[f"tier{tier}_plastic_fraction"] == 1.0
        assert figures[f"tier{tier}_updates_per_s_per_core"] > 0
        assert figures[f"tier{tier}_vs_numpy_elastic"] > 0
    assert figures["points"] == 2000


def test_bench_command_prints_one_json_object(capsys, monkeypatch):
    monkeypatch.setattr(model, "POINTS", 1000)
    assert main(["bench", "model", "--json", "--repeats", "1"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["points"] == 1000 and "tier1_updates_per_s_per_core" in figures
