"""History and control chart (scripts/accel_history.py) on records built by hand: drift and
recalibrate_by against sequences simulated with a known drift, run rules on hand-made charts."""
import datetime
import math
import random

import pytest

import accel_archive as aa
import accel_history as ah

T0 = datetime.datetime(2026, 1, 1)


def record(day, values, expanded, rig="bench"):
    return {"time": T0 + datetime.timedelta(days=day), "rig": rig, "method": "gimbal",
            "values": dict(values), "expanded": dict(expanded)}


def device_records(days, responsivity_u, U=2e-4):
    """Records whose responsivity_u follows `responsivity_u` (one value per day), the other
    parameters constant."""
    out = []
    for day, x in zip(days, responsivity_u):
        values = {n: 1.0 for n in aa.PARAMETER_NAMES}
        values["responsivity_u"] = x
        out.append(record(day, values, {n: U for n in aa.PARAMETER_NAMES}))
    return out


def binomial_band(n, p, tail=1e-4):
    """Counts k_low, k_high with P(K < k_low) <= tail and P(K > k_high) <= tail, K ~ B(n, p)."""
    pmf = [math.comb(n, k) * p ** k * (1 - p) ** (n - k) for k in range(n + 1)]
    low, cumulative = 0, 0.0
    while cumulative + pmf[low] <= tail:
        cumulative += pmf[low]
        low += 1
    high, cumulative = n, 0.0
    while cumulative + pmf[high] <= tail:
        cumulative += pmf[high]
        high -= 1
    return low, high


# --- Drift and recalibrate_by --------------------------------------------------------------------

def test_drift_on_the_line_gives_the_exact_rate_and_date():
    # no noise: responsivity_u grows 1e-5 per day; the last calibration (day 120) has
    # U = 2.05e-4, which the drift covers in 20.5 days: recalibrate by day 140 (2026-05-21)
    days = [0, 30, 61, 90, 120]
    doc = ah.history(device_records(days, [1.0 + 1e-5 * d for d in days], U=2.05e-4))
    drift = doc["drift"]["responsivity_u"]
    assert drift["rate_per_day"] == pytest.approx(1e-5, rel=1e-9)
    assert drift["significant"]
    assert doc["recalibrate_by"]["responsivity_u"] == (T0 + datetime.timedelta(days=140)).date().isoformat()
    assert doc["recalibrate_first"] == {"date": "2026-05-21", "parameter": "responsivity_u"}
    # the constant parameters do not drift
    assert doc["drift"]["offset_u"]["rate_per_day"] == pytest.approx(0.0, abs=1e-15)
    assert doc["recalibrate_by"]["offset_u"] is None
    # E_n between consecutive calibrations: (1e-5 * 30) / (sqrt(2) * 2e-4)
    assert doc["E_n_consecutive"]["responsivity_u"][0] == pytest.approx(3e-4 / (2 ** 0.5 * 2.05e-4))


def test_drift_rate_covers_the_truth_at_its_stated_rate():
    # 400 devices drifting 4e-6 per day, 8 calibrations at irregular dates, noise as stated
    # (u = U / 2): the rate's 2-sigma interval must hold the truth about 95.45 % of the time
    # (more when the reduced chi-square scaling widens it), and the rate be unbiased.
    rng = random.Random(25)
    rate, U, trials = 4e-6, 2e-4, 400
    covered, z_sum, dated = 0, 0.0, 0
    for _ in range(trials):
        days = sorted(rng.uniform(0, 365) for _ in range(8))
        xs = [1.0 + rate * d + rng.gauss(0.0, U / 2) for d in days]
        doc = ah.history(device_records(days, xs, U))
        drift = doc["drift"]["responsivity_u"]
        z = (drift["rate_per_day"] - rate) / drift["rate_std_per_day"]
        covered += abs(z) <= 2.0
        z_sum += z
        if doc["recalibrate_by"]["responsivity_u"]:
            dated += 1
            # the date follows from the fitted rate and the last calibration's U
            last = max(days)
            predicted = ah.days_between(T0, aa.parse_time(doc["recalibrate_by"]["responsivity_u"]))
            assert predicted == pytest.approx(last + U / abs(drift["rate_per_day"]), abs=1.0)
    low, _ = binomial_band(trials, math.erf(2.0 / math.sqrt(2.0)))
    assert covered >= low
    # unbiased: the mean z (each normal with variance <= 1: the chi-square scaling only
    # shrinks it) within 3.89 standard errors (two-sided 1e-4)
    assert abs(z_sum / trials) <= 3.89 / math.sqrt(trials)
    # the drift is several sigma over a year: found in nearly every sequence
    assert dated >= 0.8 * trials


def test_no_drift_rarely_gives_a_date():
    rng = random.Random(7)
    trials, dated, U = 400, 0, 2e-4
    for _ in range(trials):
        days = sorted(rng.uniform(0, 365) for _ in range(8))
        doc = ah.history(device_records(days, [1.0 + rng.gauss(0.0, U / 2) for _ in days], U))
        dated += doc["recalibrate_by"]["responsivity_u"] is not None
    # a false alarm is |z| > 2 of the rate: at most its binomial upper quantile
    _, high = binomial_band(trials, 1.0 - math.erf(2.0 / math.sqrt(2.0)))
    assert dated <= high


def test_one_record_has_no_drift():
    doc = ah.history(device_records([0], [1.0]))
    assert doc["drift"]["responsivity_u"] is None
    assert doc["E_n_consecutive"]["responsivity_u"] == []
    assert doc["recalibrate_by"]["responsivity_u"] is None


# --- Control chart run rules ---------------------------------------------------------------------

def rules(deviations, U=1.0):
    times = ["t%d" % i for i in range(len(deviations))]
    return [(f["index"], f["rule"]) for f in
            ah.run_rule_flags(times, deviations, [U] * len(deviations), "responsivity_u")]


def test_beyond_3U():
    assert rules([0.1, 3.01, -0.2, -3.01, 2.99]) == [(1, "beyond_3U"), (3, "beyond_3U")]
    assert rules([2.99, -2.99]) == []  # beyond 2U on opposite sides
    assert rules([0.3, -0.3, 2.99]) == []


def test_two_of_three_beyond_2U():
    assert rules([2.1, 0.0, 2.1]) == [(2, "two_of_three_beyond_2U")]
    assert rules([2.1, 2.1, 0.0]) == [(1, "two_of_three_beyond_2U")]
    assert rules([-2.1, 0.5, -2.5]) == [(2, "two_of_three_beyond_2U")]
    # opposite sides, or too far apart, or only one beyond: no flag
    assert rules([2.1, -2.1, 0.0]) == []
    assert rules([2.1, 0.0, 0.0, 2.1]) == []
    assert rules([1.9, 2.1, 1.9]) == []


def test_seven_one_side():
    assert rules([0.1] * 7) == [(6, "seven_one_side")]
    assert rules([-0.1] * 8) == [(6, "seven_one_side"), (7, "seven_one_side")]
    assert rules([0.1] * 6 + [-0.1] + [0.1] * 6) == []
    assert rules([0.1] * 3 + [0.0] + [0.1] * 3) == []


def test_control_chart_reference_and_flags_on_a_hand_built_chart():
    U = {n: 1.0 for n in aa.PARAMETER_NAMES}
    values = [10.0, 10.5, 9.5, 10.0, 13.5]
    records = []
    for day, v in enumerate(values):
        records.append(record(day, {n: v for n in aa.PARAMETER_NAMES}, U))
    # one record with a smaller U weighs 4 times as much in the reference
    records[0]["expanded"] = {n: 0.5 for n in aa.PARAMETER_NAMES}
    chart = ah.control_chart(records)
    reference = (4 * 10.0 + 10.5 + 9.5 + 10.0 + 13.5) / 8.0
    assert chart["reference"]["offset_w"] == pytest.approx(reference)
    assert chart["points"][4]["deviation"]["angle_uv"] == pytest.approx(13.5 - reference)
    flagged = {(f["parameter"], f["rule"], f["time"]) for f in chart["flags"]}
    assert flagged == {(n, "beyond_3U", "2026-01-05T00:00:00Z") for n in aa.PARAMETER_NAMES}
    # a given reference instead of the weighted mean
    chart = ah.control_chart(records, reference={n: 7.5 for n in aa.PARAMETER_NAMES})
    assert {f["rule"] for f in chart["flags"]} == {"beyond_3U", "two_of_three_beyond_2U"}


def test_compare_rigs_uses_each_rigs_latest():
    U = {n: 1.0 for n in aa.PARAMETER_NAMES}
    records = [record(0, {n: 0.0 for n in aa.PARAMETER_NAMES}, U, rig="a"),
               record(5, {n: 1.0 for n in aa.PARAMETER_NAMES}, U, rig="a"),
               record(3, {n: 4.0 for n in aa.PARAMETER_NAMES}, U, rig="b")]
    doc = ah.compare_rigs(records)
    pair = doc["E_n_between_rigs"][0]
    assert (pair["rig_a"], pair["rig_b"]) == ("a", "b")
    assert pair["E_n"]["angle_vw"] == pytest.approx(-3.0 / math.sqrt(2.0))
    assert not doc["consistent"]
