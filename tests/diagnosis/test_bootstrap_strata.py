"""The forward test's block bootstrap: loud blocks are resampled among themselves."""
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.diagnosis import selection


@given(arrays(float, st.integers(1, 80), elements=st.floats(0.0, 1e3, allow_subnormal=False)))
def test_loud_blocks_are_the_fewest_holding_half_the_error(sse):
    loud = selection.loudness_strata(sse) == 1
    assert loud.any()
    if sse.sum() > 0:
        assert loud.sum() >= min(selection.MIN_LOUD_BLOCKS, len(sse))
        assert sse[loud].sum() >= selection.LOUD_SHARE * sse.sum() * (1 - 1e-8)
        # Without its quietest member, the loud stratum holds less than the share (unless
        # it is at its smallest size).
        if loud.sum() > selection.MIN_LOUD_BLOCKS:
            assert sse[loud].sum() - sse[loud].min() < selection.LOUD_SHARE * sse.sum()
        # Every loud block is at least as loud as every quiet one.
        if (~loud).any():
            assert sse[loud].min() >= sse[~loud].max()


def test_resamples_keep_each_stratum_size():
    strata = np.array([0, 1, 1, 0, 2, 2, 2, 0])
    # Every block's error before is 1; after, its stratum's label: a resample's gain is
    # fixed by how many blocks of each stratum it draws (always 3, 2 and 3).
    before = np.ones(len(strata))
    after = strata.astype(float)
    gains = selection.bootstrap_gain(before, after, np.random.default_rng(1), n_boot=200,
                                     strata=strata)
    assert np.allclose(gains, 1.0 - 8.0 / 8.0)
    plain = selection.bootstrap_gain(before, after, np.random.default_rng(1), n_boot=200)
    assert plain.std() > 0.1


def test_an_effect_living_in_a_few_loud_blocks_is_significant():
    # 60 blocks: three carry 85 % of the error and the term removes 70..85 % of it there;
    # elsewhere it adds a little error (a latency in the fast moves
    # between the axes of a one-axis-at-a-time log).
    rng = np.random.default_rng(7)
    before = np.full(60, 0.15 / 57)
    before[[10, 30, 50]] = [0.45, 0.25, 0.15]
    after = before * (1.1 + 0.3 * rng.standard_normal(60))
    after[[10, 30, 50]] = before[[10, 30, 50]] * [0.2, 0.15, 0.3]
    plain = np.quantile(selection.bootstrap_gain(before, after, np.random.default_rng(0)), 0.01)
    strat = np.quantile(selection.stratified_gain(before, after, np.random.default_rng(0)), 0.01)
    assert selection.gain(before, after) > 0.6
    assert plain < selection.MIN_GAIN          # the plain bootstrap loses it
    assert strat > 0.5                         # resampled apart, it stands out


def test_one_loud_block_alone_does_not_make_a_term_significant():
    # One block holds 90 % of the error (an outlier stretch) and the term fits it away, but
    # makes every other block worse: a stratum of that one block would be in every resample
    # and the gain never questioned.
    before = np.full(60, 0.1 / 59)
    before[20] = 0.9
    after = before * 1.3
    after[20] = 0.0
    strata = selection.loudness_strata(before)
    assert strata.sum() == 2 and strata[20] == 1
    low = np.quantile(selection.stratified_gain(before, after, np.random.default_rng(0)), 0.01)
    assert selection.gain(before, after) > 0.8
    assert low < selection.MIN_GAIN


def test_noise_stays_insignificant_when_stratified():
    # A term fitted to noise: held-out errors a little worse on every block, loud or quiet.
    rng = np.random.default_rng(3)
    for _ in range(20):
        before = rng.gamma(0.5, 1.0, 60)
        after = before * (1 + 0.02 + 0.05 * rng.standard_normal(60))
        low = np.quantile(selection.stratified_gain(before, after, rng), 0.01)
        assert low < selection.MIN_GAIN


def test_the_missing_share_is_what_is_left_beyond_the_noise():
    from delta6.diagnosis.run import missing_share
    bounds = np.linspace(0, 6000, 61).astype(int)
    problem = selection.Problem(y=None, x=None, slices={}, terms={}, bounds=bounds,
                                gram=np.zeros((60, 0, 0)), xty=np.zeros((60, 0)),
                                yty=np.ones(60), noise_var=1e-4)
    floor = 6 * 6000 * 1e-4
    # A leftover that is noise alone misses nothing, however large against the gap.
    assert missing_share(problem, floor, 2 * floor) == 0.0
    assert missing_share(problem, 0.9 * floor, 2 * floor) == 0.0
    assert np.isclose(missing_share(problem, 1.5 * floor, 2 * floor), 0.25)
    assert missing_share(problem, 1.0, 0.0) == 0.0
