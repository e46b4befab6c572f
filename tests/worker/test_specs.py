"""The model-spec registry: one place, unique names, and every user reads it."""

from __future__ import annotations

import pytest

from worker.training.estimators import ModelSpec
from worker.training.specs import SPECS, DuplicateSpecError, SpecRegistry

RF_GRID = {"n_estimators": [10], "max_depth": [4]}


def test_a_name_already_taken_is_refused_naming_it():
    registry = SpecRegistry()
    first = registry.register(ModelSpec("rf-small", "rf", RF_GRID))
    assert registry["rf-small"] is first
    other = ModelSpec("rf-small", "rf", {"n_estimators": [10, 20]}, feature_set="keypoints")
    with pytest.raises(DuplicateSpecError, match="model spec name 'rf-small' is taken"):
        registry.register(other)
    assert registry["rf-small"] is first and len(registry) == 1
    with pytest.raises(ValueError, match="needs a name"):
        registry.register(ModelSpec("", "rf", RF_GRID))
    with pytest.raises(KeyError, match="unknown model spec 'nope' \\(known: rf-small\\)"):
        registry["nope"]


def test_the_registry_refuses_a_second_spec_of_a_registered_name():
    with pytest.raises(DuplicateSpecError, match="'rf-keypoints' is taken"):
        SPECS.register(ModelSpec("rf-keypoints", "rf", RF_GRID, feature_set="keypoints"))
    assert len(SPECS["rf-keypoints"].configurations()) == 16


def test_every_spec_name_is_unique_and_is_the_key_it_is_registered_under():
    assert all(name == spec.name for name, spec in SPECS.items())
    assert len(set(SPECS)) == len(SPECS)
    # Two specs that differ (feature set, family, grid, fixed parameters or operating point)
    # never share a name; and no two names hold the very same spec.
    assert len(set(map(_key, SPECS.values()))) == len(SPECS)


def _key(spec: ModelSpec):
    return (
        spec.family,
        spec.feature_set,
        repr(spec.grid),
        repr(spec.fixed),
        spec.operating_point,
    )


def test_the_two_random_forests_on_keypoints_have_names_that_say_which():
    grid, fixed = SPECS["rf-keypoints"], SPECS["rf-keypoints-default"]
    assert grid.feature_set == fixed.feature_set == "keypoints"
    assert len(grid.configurations()) == 16 and len(fixed.configurations()) == 1
    assert "rf-keypoints" in SPECS.benchmarked()
    assert "rf-keypoints-default" not in SPECS.benchmarked()


def test_the_cli_default_bootstrap_retrain_and_benchmark_read_the_registry():
    from backend.jobs.params import RetrainParams
    from worker import bootstrap
    from worker.jobs.retrain import spec_for
    from worker.training import cli

    assert cli.DEFAULT_SPEC is SPECS["rf-default"]
    assert bootstrap.KEYPOINTS_SPEC is SPECS["rf-keypoints-default"]
    # The retrain job's default spec and every registered spec are what a job can name.
    assert spec_for(RetrainParams()) is SPECS["rf-default"]
    assert spec_for(RetrainParams(spec="rf-keypoints-default")) is bootstrap.KEYPOINTS_SPEC
    with pytest.raises(ValueError, match="choose one of"):
        spec_for(RetrainParams(spec="nope"))
    # make bench-detection's default models: the registry's benchmarked grids, the window model
    # (tcn) among them as a spec of its own family, last as before.
    assert cli.ALL_MODELS.split(",") == list(SPECS.benchmarked())
    assert cli.ALL_MODELS.split(",")[-1] == "tcn" and SPECS["tcn"].family == "tcn"
    trainers = cli.make_trainers(["rf-keypoints", "rf-default", "tcn"])
    assert [t.spec for t in trainers] == [SPECS["rf-keypoints"], SPECS["rf-default"], SPECS["tcn"]]
    with pytest.raises(ValueError, match="unknown model 'nope'"):
        cli.make_trainers(["rf", "nope"])
