"""Benchmark helpers: medians and the JSON form of the figures."""
import json

from contfab.bench import median_seconds, print_figures


def test_median_of_repeats_counts_calls():
    calls = []
    t = median_seconds(lambda: calls.append(1), repeats=3, warmup=2)
    assert len(calls) == 5 and t >= 0.0


def test_json_output_is_one_object(capsys):
    print_figures("x", {"a_per_s": 1.5, "n": 3}, as_json=True)
    assert json.loads(capsys.readouterr().out) == {"a_per_s": 1.5, "n": 3}
