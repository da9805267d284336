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


# ----------------------------------------------------------------------------- the compiled validation
def random_trace_columns(rng, n=60):
    t = np.cumsum(rng.uniform(0.1, 0.3, n))
    has = rng.random(n) < 0.8
    cols = {"t": t, "v": rng.uniform(0.0, 30.0, n), "a": rng.uniform(-8.0, 3.0, n),
            "gap": np.where(has, rng.uniform(-1.0, 120.0, n), np.inf),
            "v_lead": np.where(has, rng.uniform(0.0, 30.0, n), 0.0), "a_lead": rng.uniform(-8.0, 3.0, n),
            "lead_id": np.where(has, 1.0, -1.0), "a_y": rng.normal(0.0, 0.3, n), "d2": rng.uniform(0.1, 1.0, n),
            "d3": rng.uniform(0.1, 1.0, n)}
    return cols


def checked_the_slow_way(cols, **kw):
    """The field-by-field checks alone (float lists never take the compiled pass)."""
    return EgoTrace(**{k: v.tolist() for k, v in cols.items()}, **kw)


def test_compiled_validation_keeps_valid_columns_and_equals_the_checks():
    rng = np.random.default_rng(0)
    for k in range(40):
        cols = random_trace_columns(rng)
        if k % 3 == 0:
            for name in ("a_lead", "lead_id", "a_y", "d2", "d3"):
                del cols[name]
        elif k % 3 == 1:  # strided columns (views into a world trace's (T, B, S) arrays)
            cols["lead_id"] = np.repeat(cols["lead_id"][:, None], 3, axis=1)[:, 1]
            cols["a_lead"] = np.repeat(cols["a_lead"][:, None], 2, axis=1)[:, 0]
        fast = EgoTrace(**cols, set_speed=25.0, time_gap=1.5)
        assert fast._valid_as_given()
        assert all(getattr(fast, name) is value for name, value in cols.items())  # kept as given
        slow = checked_the_slow_way(cols, set_speed=25.0, time_gap=1.5)
        for name, value in cols.items():
            assert np.array_equal(getattr(slow, name), value), name
        assert score_episode(fast).to_dict() == score_episode(slow).to_dict()


@pytest.mark.parametrize("name, index, value, message", [
    ("v", 5, np.nan, "'v' is NaN at sample 5"),
    ("gap", 3, -np.inf, "'gap' must not be -inf"),
    ("v_lead", 7, np.inf, "'v_lead' must be finite where a vehicle is ahead"),
    ("a_y", 2, np.inf, "'a_y' must be finite"),
    ("t", 4, 0.0, "strictly increasing"),
    ("v", 9, -0.5, "must be >= 0"),
])
def test_compiled_validation_hands_bad_columns_to_the_named_checks(name, index, value, message):
    cols = random_trace_columns(np.random.default_rng(1))
    cols["gap"][7] = 10.0  # sample 7 has a vehicle ahead
    cols[name][index] = value
    with pytest.raises(ValueError, match=message):
        EgoTrace(**cols)


def test_v_lead_without_a_vehicle_ahead_is_zeroed_as_before():
    """A v_lead other than +0.0 where the gap is inf makes the checks (not the compiled pass)
    take the trace, and they set it to 0 -- including -0.0."""
    cols = random_trace_columns(np.random.default_rng(2))
    cols["gap"][[3, 4]] = np.inf
    cols["v_lead"][3], cols["v_lead"][4] = 12.0, -0.0
    trace = EgoTrace(**cols)
    assert trace.v_lead[3] == 0.0 and np.signbit(trace.v_lead[4]) == np.False_
    assert trace.v_lead is not cols["v_lead"]  # the checks replaced the column


def test_a_csv_with_a_byte_order_mark_reads(tmp_path):
    """Spreadsheet programs start UTF-8 CSV files with a byte-order mark."""
    body = "t,v,a,gap,v_lead\n" + "".join(f"{0.2 * k:.1f},20,0,30,20\n" for k in range(10))
    plain, bom = tmp_path / "plain.csv", tmp_path / "bom.csv"
    plain.write_text(body, encoding="utf-8")
    bom.write_bytes(b"\xef\xbb\xbf" + body.encode())
    a, b = EgoTrace.from_csv(plain), EgoTrace.from_csv(bom)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.v, b.v)


@pytest.mark.parametrize("body,words", [
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n0.2,inf,0,5,1\n0.4,1,0,5,1\n", r"'v' must be finite, got inf at sample 1 \(line 3\)"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n0.4,1,0,5,1\n0.2,1,0,5,1\n", r"'t' must be strictly increasing \(sample 2 \(line 4\): "
                                                                 r"0.2 after 0.4\)"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n0.2,-3,0,5,1\n", r"must be >= 0, got -3.0 at sample 1 \(line 3\)"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n", "at least 2 samples"),
])
def test_whole_trace_errors_name_the_file_and_the_line(tmp_path, body, words):
    path = tmp_path / "drive.csv"
    path.write_text(body)
    with pytest.raises(ValueError, match=words) as err:
        EgoTrace.from_csv(path)
    assert str(err.value).startswith(str(path)) and "np.float64" not in str(err.value)


def test_a_csv_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes("t,v,a,gap,v_lead\n0,1,0,5,1\n0.2,1,0,5,1 \xe9\n".encode("latin-1"))
    with pytest.raises(ValueError, match=r"latin1\.csv: not UTF-8 text \(byte \d+"):
        EgoTrace.from_csv(path)


@pytest.mark.parametrize("body,words", [
    # a blank line after the header and another between samples: the reader skips them, the lines still count
    ("t,v,a,gap,v_lead\n\n0,1,0,5,1\n\n0.2,-3,0,5,1\n", r"must be >= 0, got -3.0 at sample 1 \(line 5\)"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n\n\n0.4,1,0,5,1\n0.2,1,0,5,1\n", r"strictly increasing \(sample 2 \(line 6\): "),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n\n0.2,1,0,5,nan\n", r"line 4: column 'v_lead' is NaN"),
    ("t,v,a,gap,v_lead\n0,1,0,5,1\n\n0.2,1,0,5,1,9\n", r"line 4: more cells than columns"),
    # a quoted cell spanning two lines: the next sample starts two lines further on
    ('t,v,a,gap,v_lead\n0,1,0,5,"1\n"\n0.2,inf,0,5,1\n', r"'v' must be finite, got inf at sample 1 \(line 4\)"),
])
def test_lines_are_the_files_own_with_blank_lines(tmp_path, body, words):
    path = tmp_path / "drive.csv"
    path.write_text(body)
    with pytest.raises(ValueError, match=words) as err:
        EgoTrace.from_csv(path)
    assert str(err.value).startswith(str(path))


def test_an_infinite_v_lead_names_the_sample_and_the_line(tmp_path):
    path = tmp_path / "drive.csv"
    path.write_text("t,v,a,gap,v_lead\n0,20,0,30,20\n0.2,20,0,30,20\n\n0.4,20,0,30,inf\n")
    with pytest.raises(ValueError, match=r"drive.csv: trace column 'v_lead' must be finite where a vehicle is ahead, "
                                         r"got inf at sample 2 \(line 5\)"):
        EgoTrace.from_csv(path)
    path.write_text("t,v,a,gap,v_lead\n0,20,0,30,20\n0.2,20,0,-inf,20\n")
    with pytest.raises(ValueError, match=r"'gap' must not be -inf, got -inf at sample 1 \(line 3\)"):
        EgoTrace.from_csv(path)
    path.write_text("t,v,a,gap,v_lead\n0,20,0,30,20\n0.2,20,0,inf,inf\n")  # no vehicle ahead: v_lead ignored
    assert EgoTrace.from_csv(path).v_lead[1] == 0.0


def test_an_infinite_v_lead_in_arrays_names_the_sample():
    c = columns()
    c["v_lead"][4] = -np.inf
    with pytest.raises(ValueError, match=r"'v_lead' must be finite where a vehicle is ahead, got -inf at sample 4"):
        EgoTrace(**c)


def test_a_repeated_column_is_refused_not_silently_overwritten(tmp_path):
    path = tmp_path / "drive.csv"
    path.write_text("t,v,a,gap,v_lead,v\n0,20,0,30,20,5\n0.2,20,0,30,20,5\n")
    with pytest.raises(ValueError, match=r"drive.csv: column\(s\) \['v'\] appear more than once in the header"):
        EgoTrace.from_csv(path)


def test_an_unreadable_csv_record_names_the_file_and_line(tmp_path):
    """The csv module's own errors (here a cell over its size limit) are not ValueErrors: named, not raw."""
    import csv

    path = tmp_path / "drive.csv"
    path.write_text("t,v,a,gap,v_lead\n0,20,0,30,20\n0.2,20,0,30," + "9" * 50 + "\n")
    old = csv.field_size_limit(10)
    try:
        with pytest.raises(ValueError, match=r"drive.csv, line 3: not a readable CSV record"):
            EgoTrace.from_csv(path)
    finally:
        csv.field_size_limit(old)
