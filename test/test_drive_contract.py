"""The drive's limits as numbers (interface.DriveLimits): the layout, its checks, the codes."""

import math

import pytest
from wet_eha_thermal.estimator.limits import fallback_limits
from wet_eha_thermal.interface import DriveLimits, limit_status, LimitStatus


def test_layout_round_trip_at_fixed_places():
    d = DriveLimits(stamp_ns=1_790_000_123_456_789_012, sequence=42,
                    status=LimitStatus.UNCERTAIN, binding_A=12.5, binding_horizon_s=10.0,
                    horizons_s=(math.inf, 10.0, 60.0), limits_A=(8.0, 12.5, math.inf))
    data = d.to_data()
    # the places a C++ drive reads, by index
    assert data[:8] == [1.0, 1_790_000_123.0, 456_789_012.0, 42.0, 2.0, 12.5, 10.0, 3.0]
    assert data[8:] == [math.inf, 8.0, 10.0, 12.5, 60.0, math.inf]
    assert DriveLimits.from_data(data) == d


@pytest.mark.parametrize('data, message', [
    ([], 'not drive limits v1'),
    ([2.0, 0, 0, 1, 0, 5.0, 10.0, 0], 'not drive limits v1'),
    ([1.0, 0, 0, 1, 0, 5.0, 10.0, 2, 10.0, 5.0], 'n = 2 for 10 numbers'),
    ([1.0, 0, 0, 1, 0, 5.0, 10.0, 1, 10.0, -1.0], 'negative or NaN'),
    ([1.0, 0, 0, 1, 0, math.nan, 10.0, 0], 'negative or NaN'),
])
def test_malformed_limits_are_refused(data, message):
    with pytest.raises(ValueError, match=message):
        DriveLimits.from_data(data)


def test_an_unknown_status_code_reads_as_a_fallback():
    data = [1.0, 0, 0, 1, 99.0, 5.0, 10.0, 0]
    assert DriveLimits.from_data(data).status == LimitStatus.OTHER


@pytest.mark.parametrize('reason, code', [
    ('stale inputs: speed_rad_s', LimitStatus.STALE_INPUTS),
    ('uncertain: magnet 1 sigma 12.0 K > 10 K', LimitStatus.UNCERTAIN),
    ('behind: the estimator had no time to compute them', LimitStatus.BEHIND),
    ('behind: the model is catching up with its inputs', LimitStatus.BEHIND),
    ('failed: the limits could not be computed', LimitStatus.FAILED),
    ('a reason not known here', LimitStatus.OTHER),
])
def test_each_fallback_reason_has_its_code(reason, code):
    limits = fallback_limits(3.0, (10.0, 60.0), 10.0, reason)
    assert limit_status(limits.status, limits.reason) == code
    assert limit_status('ok', '') == LimitStatus.OK
