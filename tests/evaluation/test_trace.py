"""EgoTrace: validation with clear errors, CSV in and out."""

import numpy as np
import pytest

from acc_gym.evaluation import EgoTrace, ScoringConfig, score_episode


def columns(n=6):
    return dict(t=np.arange(n) * 0.5, v=np.full(n, 20.0), a=np.zeros(n), gap=np.full(n, 32.0),
                v_lead=np.full(n, 20.0))


def test_csv_round_trip_scores_the_same(tmp_path):
    c = columns()
    c["gap"][:2] = np.inf  # no vehicle ahead yet
    tr = EgoTrace(**c, lead_id=np.array([-1, -1, 3, 3, 3, 3.0]), time_gap=1.5)
    path = tmp_path / "drive.csv"
    tr.to_csv(path)
    text = path.read_text().splitlines()
    assert text[0] == "t,v,a,gap,v_lead,lead_id"
    assert text[1].split(",")[3] == ""  # inf written as an empty cell
    back = EgoTrace.from_csv(path, time_gap=1.5)
    np.testing.assert_array_equal(back.gap, tr.gap)
    assert score_episode(back).to_dict() == score_episode(tr).to_dict()


def test_minimal_csv_with_only_the_required_columns(tmp_path):
    path = tmp_path / "min.csv"
    path.write_text("t,v,a,gap,v_lead\n0,20,0,22,20\n1,20,0,22,20\n2,20,0.5,,\n")
    tr = EgoTrace.from_csv(path)
    assert tr.n == 3 and np.isinf(tr.gap[2]) and tr.v_lead[2] == 0.0
    r = score_episode(tr, ScoringConfig(tau1=1.0, transient=0.0))
    assert r.item("safety").qualified


@pytest.mark.parametrize("field", ["t", "v", "a", "gap", "v_lead"])
def test_nan_is_rejected_naming_the_column(field):
    c = columns()
    c[field][3] = np.nan
    with pytest.raises(ValueError, match=f"'{field}' is NaN at sample 3"):
        EgoTrace(**c)


def test_mismatched_lengths_and_bad_times():
    c = columns()
    c["v_lead"] = np.full(5, 20.0)
    with pytest.raises(ValueError, match="'v_lead' has 5 samples but 't' has 6"):
        EgoTrace(**c)
    c = columns()
    c["t"][3] = c["t"][2]
    with pytest.raises(ValueError, match="strictly increasing"):
        EgoTrace(**c)
    c = columns()
    c["v"][1] = -1.0
    with pytest.raises(ValueError, match="ego speed"):
        EgoTrace(**c)
    with pytest.raises(ValueError, match="time_gap"):
        EgoTrace(**columns(), time_gap=-1.5)
    c = columns()
    c["v_lead"][2] = np.inf  # a vehicle is ahead (gap finite) but its speed is not finite
    with pytest.raises(ValueError, match="v_lead"):
        EgoTrace(**c)


@pytest.mark.parametrize("content, message", [
    ("t,v,a,gap\n0,1,0,5\n", "missing column"),
    ("t,v,a,gap,v_lead,speed\n0,1,0,5,1,3\n", "unknown column"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n1,1,abc,5,1\n", "line 3: column 'a' is not a number"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n1,nan,0,5,1\n", "line 3: column 'v' is NaN"),
])
def test_broken_csv_files_give_clear_errors(tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        EgoTrace.from_csv(path)
