"""bench.compare: two sets of accuracy runs per log, and whether they differ more than the seeds do."""
from __future__ import annotations

import json

import pytest

from bench import compare


def test_the_permutation_p_is_the_share_of_splits_as_far_apart_hand_counted():
    # pooled 0..5: of the 20 splits into 3 + 3, only {3, 4, 5} and {2, 4, 5} have a median
    # 3 above the other's (4 against 1)
    assert compare.median_shift_p([3, 4, 5], [0, 1, 2]) == pytest.approx(2 / 20)
    assert compare.median_shift_p([0, 1, 2], [3, 4, 5]) == pytest.approx(2 / 20)    # the other direction
    assert compare.median_shift_p([1, 1, 1], [1, 1, 1]) == 1.0                      # no difference at all


def test_many_splits_are_drawn_and_a_clear_shift_is_rare():
    before = [0.20 + 0.01 * i for i in range(12)]
    after = [0.10 + 0.01 * i for i in range(12)]
    p = compare.median_shift_p(before, after, draws=5000)
    assert p < 0.01
    assert compare.median_shift_p(before, after, draws=5000) == p                    # seeded


def _rows(path, log, errors):
    rows = [{"log": log, "seed": s, "error": e, "rel_max": e} for s, e in errors]
    path.write_text(json.dumps(rows))
    return str(path)


def test_compare_counts_runs_over_the_targets_on_the_common_seeds(tmp_path, capsys):
    before = _rows(tmp_path / "a.json", "edmonton", [(0, 0.20), (1, 0.10), (2, 0.60), (3, 0.30)])
    after = _rows(tmp_path / "b.json", "edmonton", [(0, 0.12), (1, 0.13), (2, 0.14), (7, 0.90)])
    assert compare.main(["--before", before, "--after", after]) == 0
    out = capsys.readouterr().out.splitlines()
    # seeds 0-2 only (3 and 7 are one side's); before: median 0.20, two over 0.15, one over 0.5
    assert out[2].startswith("| edmonton | 3 (0-2) | 0.200 / 0.200; 2; 1 | 0.130 / 0.130; 0; 0 |")


def test_seeds_beyond_the_first_three_show_no_median_of_them_and_their_runs_of_seeds(tmp_path, capsys):
    before = _rows(tmp_path / "a.json", "intel", [(5, 0.1), (12, 0.2), (13, 0.3), (14, 0.4)])
    after = _rows(tmp_path / "b.json", "intel", [(5, 0.1), (12, 0.2), (13, 0.3), (14, 0.4)])
    assert compare.main(["--before", before, "--after", after]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2].startswith("| intel | 4 (5, 12-14) | - / 0.250; 3; 0 | - / 0.250; 3; 0 |"), out[2]   # 3 over 0.15


def test_the_real_bags_count_their_worst_relation_over_half_a_metre(tmp_path):
    rows = {("aces", s, 0): {"log": "aces", "seed": s, "error": e, "rel_max": m}
            for s, e, m in [(0, 0.044, 0.3), (1, 0.046, 0.7), (2, 0.050, 0.4)]}
    line, = compare.compare(rows, rows)
    assert line["before"]["over_target"] == 2 and line["before"]["over_half_metre"] == 1
    assert line["before"]["median_first3"] == pytest.approx(0.046)


def test_each_phase_of_a_seed_is_its_own_run_and_rows_without_one_are_phase_0s(tmp_path, capsys):
    # before: phase 0 rows written before phases existed; after: the same seeds at phases 0 and 1
    before = tmp_path / "a.json"
    before.write_text(json.dumps([{"log": "aces", "seed": s, "error": e, "rel_max": 0.4}
                                  for s, e in [(0, 0.041), (1, 0.047), (2, 0.040)]]
                                 + [{"log": "aces", "seed": s, "phase": 1, "error": 0.050, "rel_max": 0.8}
                                    for s in (0, 1, 2)]))
    after = tmp_path / "b.json"
    after.write_text(json.dumps([{"log": "aces", "seed": s, "phase": ph, "error": 0.042, "rel_max": 0.4}
                                 for s in (0, 1, 2) for ph in (0, 1)]))
    line, = compare.compare(compare.read_rows([str(before)]), compare.read_rows([str(after)]))
    assert line["runs"] == 6 and line["phases"] == [0, 1]
    # seeds 0-2 at phase 0: 0.041 0.047 0.040 -> 0.041; all six: 0.041 0.047 0.040 0.050 0.050 0.050 -> 0.0485
    assert line["before"]["median_first3"] == pytest.approx(0.041)
    assert line["before"]["median"] == pytest.approx(0.0485)
    assert line["before"]["over_half_metre"] == 3 and line["after"]["over_half_metre"] == 0
    assert compare.main(["--before", str(before), "--after", str(after)]) == 0
    row = capsys.readouterr().out.splitlines()[2]
    assert row.startswith("| aces | 3 (0-2) x phases 0-1: 6 runs | 0.0410 / 0.0485;"), row


@pytest.mark.parametrize("content", ["not json", '[{"log": "aces"}]'])
def test_a_file_that_is_not_bench_rows_is_one_line_and_exit_2(tmp_path, capsys, content):
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    assert compare.main(["--before", str(bad), "--after", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "bad.json" in err and len(err.strip().splitlines()) == 1


def test_no_common_seed_is_one_line_and_exit_2(tmp_path, capsys):
    a = _rows(tmp_path / "a.json", "intel", [(0, 0.1)])
    b = _rows(tmp_path / "b.json", "intel", [(1, 0.1)])
    assert compare.main(["--before", a, "--after", b]) == 2
    assert "no log, seed and phase in common" in capsys.readouterr().err
