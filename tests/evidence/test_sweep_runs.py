"""A sweep's chunk of runs (evidence.sweep.run_chunk): pure, in-process."""

import pytest

from evidence.sweep import RunFailed, ScenarioSpec, run_chunk


def test_a_run_that_raises_is_named_so_that_it_can_be_taken_apart():
    """A chunk is the unit a pool or Dask retries and reports; the error says which of its runs failed and how."""
    fine = ScenarioSpec(kind="crossing", seed=1, duration=0.5, strategy="scale_only")
    broken = ScenarioSpec(kind="crossing", seed=2, duration=0.5, strategy="nonsense",
                          overrides=(("ssm.reaction_time", 0.12),))
    assert [r["seed"] for r in run_chunk([fine])] == [1]
    with pytest.raises(RunFailed) as failed:
        run_chunk([fine, broken])
    text = str(failed.value)
    assert text.startswith("crossing seed 2, 0.5 s, nonsense, ") and '"ssm.reaction_time": 0.12' in text
    assert "ValueError: unknown strategy 'nonsense'" in text
    assert isinstance(failed.value.__cause__, ValueError)
