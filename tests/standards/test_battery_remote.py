"""The ISO 15622 battery run through an exchange of observations and actions (the leaderboard's
sandbox): the same scenes and the same verdict, to the bit, as the battery run with the local
controller; the exchange's rounds are lockstep; bad answers are named."""

import copy

import numpy as np
import pytest

from acc_gym.evaluation.runner import _action, as_action, declared_time_gap, load_controller
from acc_gym.standards.battery import (BATTERIES, ISO15622_V1, SEEDS, battery_cases, iso15622_report,
                                       remote_iso15622_report)


class Local:
    """An exchange served by local copies of ``controller`` as the sandbox serves it: one copy per
    slot, made before its first call, ``reset()`` when its row starts an episode; records the rounds."""

    def __init__(self, controller):
        self.pristine = load_controller(controller)
        self.copies, self.rounds = {}, []

    def __call__(self, obs, starts, slots):
        self.rounds.append((obs.shape, starts.copy(), np.asarray(slots).copy()))
        out = []
        for row, start, slot in zip(obs, starts, slots):
            ctl = self.copies.setdefault(int(slot), copy.deepcopy(self.pristine))
            if start and hasattr(ctl, "reset"):
                ctl.reset()
            out.append(float(as_action(_action(ctl, row.astype(np.float32)))[0]))
        return np.array(out)


@pytest.mark.parametrize("controller", ["acc", "idm"])
def test_the_remote_battery_gives_the_local_verdict_to_the_bit(controller):
    local = iso15622_report(controller)
    ex = Local(controller)
    remote = remote_iso15622_report(ex, declared_time_gap(ex.pristine))
    assert remote.to_dict() == local.to_dict()  # measured values, limits, where, failures, drives, collisions
    assert remote.passed is local.passed and len(remote.drives) == 30
    # all 30 episodes in lockstep: the first round carries every one, each starting in its own slot
    shape, starts, slots = ex.rounds[0]
    assert shape[0] == 30 and starts.all() and list(slots) == list(range(30))
    assert not any(r[1].any() for r in ex.rounds[1:])  # no row starts twice
    assert [r[0][0] for r in ex.rounds] == sorted((r[0][0] for r in ex.rounds), reverse=True)  # rows only finish
    assert len(ex.copies) == 30


def test_a_declared_time_gap_gives_the_local_verdict_too():
    class Gap12:
        time_gap = 1.2

        def __init__(self):
            from acc_gym_agents.controllers.linear import LinearACC

            self.law = LinearACC()

        def predict(self, obs, deterministic=True):
            return self.law.predict(obs, deterministic)

    ex = Local(Gap12())
    remote = remote_iso15622_report(ex, 1.2, seeds=(0,))
    assert remote.to_dict() == iso15622_report(Gap12(), seeds=(0,)).to_dict()


def test_both_ways_build_the_same_scenes():
    cases = battery_cases()
    assert len(cases) == len(BATTERIES[ISO15622_V1]) * len(SEEDS)
    again = battery_cases(ISO15622_V1, SEEDS)
    assert [(n, s, sc.id, sc.seed) for n, s, sc in cases] == [(n, s, sc.id, sc.seed) for n, s, sc in again]
    assert cases[0][0] == "follow at 60 km/h (seed 0)" and cases[-1][0] == "cut-out (seed 2)"


def test_first_slot_offsets_the_slots_and_a_bad_one_is_named():
    ex = Local("acc")
    remote_iso15622_report(ex, None, seeds=(0,), first_slot=100)
    assert list(ex.rounds[0][2]) == list(range(100, 110))
    with pytest.raises(ValueError, match="first_slot .* -1"):
        remote_iso15622_report(ex, None, first_slot=-1)
    with pytest.raises(ValueError, match="unknown battery 'iso15622-v0'"):
        remote_iso15622_report(ex, None, battery="iso15622-v0")


def test_bad_answers_are_named_and_the_exchange_s_errors_end_the_run():
    with pytest.raises(ValueError, match="answered 10 observations with 3 values"):
        remote_iso15622_report(lambda obs, starts, slots: np.zeros(3), None, seeds=(0,))
    with pytest.raises(ValueError, match=r"action is NaN: nan \(at follow at 60 km/h \(seed 0\)\)"):
        remote_iso15622_report(lambda obs, starts, slots: np.full(len(slots), np.nan), None, seeds=(0,))

    class Gone(Exception):
        pass

    def dies(obs, starts, slots):
        raise Gone("the controller's process died")

    with pytest.raises(Gone):
        remote_iso15622_report(dies, None, seeds=(0,))
