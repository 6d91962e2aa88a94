"""heartpole.people: populations of people, their seeded vectorized sampling, traits and validation.

Statistical tolerances: a Kolmogorov-Smirnov distance below ``2.23 / sqrt(n)`` (a false failure has
probability 1e-4 per column) and frequencies within 5 binomial standard deviations (about 6e-7 each).
"""

from __future__ import annotations

import dataclasses
import json
import math

import gymnasium as gym
import numpy as np
import pytest

from heartpole.optimum import check_beer
from heartpole.parameters import Params
from heartpole.people import DEFAULT_COHORT, PERSON_FIELDS, TASK_FIELDS, People, Person, Uniform

N = 20_000
KS_BOUND = 2.23 / math.sqrt(N)


def uniform_population() -> People:
    return People(
        heart_attack_proclivity=Uniform(0.3, 0.7),
        decay_rate=0.95,
        sleep_half_hours=Uniform(12, 20),
        wake_alertness=Uniform((0.6, 1.2), (0.8, 1.4)),
    )


def ks_distance(values: np.ndarray, low: float, high: float) -> float:
    """The largest gap between the empirical CDF of ``values`` and U(low, high)'s."""
    x = np.sort(values)
    cdf = (x - low) / (high - low)
    n = len(x)
    return float(max((np.arange(1, n + 1) / n - cdf).max(), (cdf - np.arange(n) / n).max()))


def test_person_fields_are_params_fields_but_the_tasks() -> None:
    names = [f.name for f in dataclasses.fields(Params)]
    assert set(PERSON_FIELDS) | set(TASK_FIELDS) == set(names)
    assert set(TASK_FIELDS) == {"max_steps", "heart_attack_penalty"}


def test_sampling_is_reproducible_by_seed() -> None:
    for people in (uniform_population(), People.default()):
        a = people.sample(np.random.default_rng(7), 1000)
        b = people.sample(np.random.default_rng(7), 1000)
        c = people.sample(np.random.default_rng(8), 1000)
        np.testing.assert_array_equal(a.values, b.values)
        np.testing.assert_array_equal(a.person, b.person)
        assert not np.array_equal(a.values, c.values)


def test_uniform_columns_are_uniform_and_fixed_ones_fixed() -> None:
    people = uniform_population()
    drawn = people.sample(np.random.default_rng(1), N)
    assert people.columns == (
        "heart_attack_proclivity",
        "decay_rate",
        "sleep_half_hours",
        "wake_alertness_low",
        "wake_alertness_high",
    )
    assert drawn.values.shape == (N, 5) and drawn.values.dtype == np.float64
    assert np.all(drawn.person == -1) and drawn.names == [""] * N
    for column, (low, high) in {
        "heart_attack_proclivity": (0.3, 0.7),
        "wake_alertness_low": (0.6, 0.8),
        "wake_alertness_high": (1.2, 1.4),
    }.items():
        values = drawn.column(column)
        assert low <= values.min() and values.max() <= high
        assert ks_distance(values, low, high) < KS_BOUND, column
    assert np.all(drawn.column("decay_rate") == 0.95)
    # the two ends of the waking interval are drawn independently
    low_end, high_end = drawn.column("wake_alertness_low"), drawn.column("wake_alertness_high")
    assert abs(np.corrcoef(low_end, high_end)[0, 1]) < 5 / math.sqrt(N)


def test_integer_fields_draw_every_integer_of_the_range_equally() -> None:
    drawn = uniform_population().sample(np.random.default_rng(2), N)
    sleep = drawn.column("sleep_half_hours")
    assert np.all(sleep == np.round(sleep))
    values, counts = np.unique(sleep, return_counts=True)
    assert values.tolist() == list(range(12, 21))  # both ends included
    p = 1 / 9
    assert np.all(np.abs(counts - N * p) < 5 * math.sqrt(N * p * (1 - p)))


def test_a_cohort_draws_each_person_equally_and_gives_their_values() -> None:
    people = People.default()
    drawn = people.sample(np.random.default_rng(3), N)
    counts = np.bincount(drawn.person, minlength=len(people.cohort))
    p = 1 / len(people.cohort)
    assert np.all(np.abs(counts - N * p) < 5 * math.sqrt(N * p * (1 - p)))
    for index in (0, 1, N - 1):
        person = people.cohort[drawn.person[index]]
        assert drawn.names[index] == person.name
        assert drawn.params(index) == person.params()
    base = Params(max_steps=300, heart_attack_penalty=50.0)
    assert drawn.params(0, base).max_steps == 300
    np.testing.assert_array_equal(drawn.column("max_steps", base), np.full(N, 300.0))
    with pytest.raises(ValueError, match="unknown column 'speed'; columns: .*'wake_alertness_low'"):
        drawn.column("speed")


def test_traits_and_their_bounds_make_a_box_holding_every_draw() -> None:
    for people, traits in (
        (
            uniform_population(),
            ("heart_attack_proclivity", "sleep_half_hours", "wake_alertness_low", "wake_alertness_high"),
        ),
        (People.default(), People.default().columns),
    ):
        assert people.traits == traits
        low, high = people.trait_bounds()
        box = gym.spaces.Box(low, high, dtype=np.float32)
        traits_drawn = people.sample(np.random.default_rng(4), 5000).traits()
        assert traits_drawn.dtype == np.float32 and traits_drawn.shape == (5000, len(traits))
        assert all(box.contains(row) for row in traits_drawn[:500])
        assert np.all(traits_drawn >= low) and np.all(traits_drawn <= high)
    low, high = uniform_population().trait_bounds()
    np.testing.assert_allclose(low, [0.3, 12, 0.6, 1.2], rtol=1e-7)
    np.testing.assert_allclose(high, [0.7, 20, 0.8, 1.4], rtol=1e-7)


def test_the_default_cohort_is_the_documented_design() -> None:
    """The docstring's recipe (a Latin hypercube from default_rng(26), rounded) gives the table, Ada aside."""
    rng = np.random.default_rng(26)
    n = 23

    def lhs() -> np.ndarray:
        return (rng.permutation(n) + rng.uniform(size=n)) / n

    proclivity = np.round((0.3 + 0.5 * lhs()) / 0.05) * 0.05
    sleep = np.round(12 + 8 * lhs()).astype(int)
    wake_low = np.round((0.5 + 0.4 * lhs()) / 0.05) * 0.05
    width = np.round((0.4 + 0.4 * lhs()) / 0.1) * 0.1
    decay = np.round((0.93 + 0.04 * lhs()) / 0.01) * 0.01
    decay = np.where(proclivity < 0.4, np.minimum(decay, 0.95), decay)
    designed = [
        (round(p, 2), round(d, 2), int(s), (round(w, 2), round(w + x, 2)))
        for p, d, s, w, x in zip(proclivity, decay, sleep, wake_low, width)
    ]
    assert DEFAULT_COHORT[0][1:] == (0.5, 0.97, 16, (0.7, 1.3))  # Ada: v0's own numbers
    assert Person("Ada", **dict(People.default().cohort[0].traits)).params() == Params()
    assert [row[1:] for row in DEFAULT_COHORT[1:]] == designed
    assert len({row[0] for row in DEFAULT_COHORT}) == 24


def test_every_default_person_passes_the_optimums_beer_bound() -> None:
    """The fast half of coverage (the full solve of all of them is tests/test_optimum_people.py, slow)."""
    for person in People.default().cohort:
        check_beer(person.params())


def test_resolve_and_to_dict() -> None:
    assert People.resolve(None) is None
    assert People.resolve("default") == People.default()
    people = uniform_population()
    assert People.resolve(people) is people
    with pytest.raises(ValueError, match=r"unknown population 'nope'; named populations: \['default'\]"):
        People.resolve("nope")
    with pytest.raises(TypeError, match="people must be a People"):
        People.resolve(3)
    assert json.loads(json.dumps(people.to_dict())) == {
        "fields": {
            "heart_attack_proclivity": {"uniform": [0.3, 0.7]},
            "decay_rate": 0.95,
            "sleep_half_hours": {"uniform": [12, 20]},
            "wake_alertness": {"uniform": [[0.6, 1.2], [0.8, 1.4]]},
        }
    }
    cohort = json.loads(json.dumps(People.default().to_dict()))["cohort"]
    assert cohort[0] == {
        "name": "Ada",
        "heart_attack_proclivity": 0.5,
        "decay_rate": 0.97,
        "sleep_half_hours": 16,
        "wake_alertness": [0.7, 1.3],
    }


def test_people_are_frozen_and_hashable() -> None:
    people = People.default()
    with pytest.raises(dataclasses.FrozenInstanceError):
        people.cohort = ()
    assert hash(people) == hash(People(cohort=people.cohort))
    assert uniform_population() == uniform_population()


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: People(), ValueError, r"needs a cohort or at least one of \['heart_attack_proclivity'"),
        (lambda: People(speed=1.0), TypeError, r"People\(\) got an unexpected keyword argument 'speed'; it accepts"),
        (lambda: People(max_steps=Uniform(100, 200)), TypeError, "'max_steps': max_steps and heart_attack_penalty are"),
        (lambda: People(heart_attack_penalty=50.0), TypeError, "are the task's"),
        (
            lambda: People(decay_rate=Uniform(0.9, 1.2)),
            ValueError,
            r"decay_rate must be a finite number in \(0.0, 1.0\]",
        ),
        (lambda: People(sleep_half_hours=Uniform(12.5, 20)), ValueError, "sleep_half_hours must be an integer >= 0"),
        (
            lambda: People(wake_alertness=Uniform((0.6, 1.0), (1.2, 1.4))),
            ValueError,
            "wake_alertness must be .low, high. with low <= high",
        ),
        (lambda: People(heart_attack_proclivity=1.5), ValueError, "heart_attack_proclivity must be a finite number"),
        (lambda: Uniform(0.7, 0.3), ValueError, r"needs low <= high"),
        (lambda: Uniform("a", 1.0), ValueError, "a finite number or a .low, high. pair"),
        (lambda: Uniform(0.1, math.inf), ValueError, "must be a finite number, got inf"),
        (lambda: Uniform((0.1, 0.2), 0.3), ValueError, "needs low <= high"),
        (lambda: Person("", decay_rate=0.9), ValueError, "a person's name must be a non-empty string"),
        (lambda: Person("Ada"), ValueError, r"person 'Ada': give at least one of"),
        (lambda: Person("Ada", decay_rate=0.0), ValueError, r"person 'Ada': decay_rate must be a finite number"),
        (lambda: Person("Ada", max_steps=10), TypeError, "Person\\(\\) got an unexpected keyword argument 'max_steps'"),
        (lambda: Person("Ada", mood=1), TypeError, "Person\\(\\) got an unexpected keyword argument 'mood'"),
        (
            lambda: People(cohort=[Person("A", decay_rate=0.9), Person("A", decay_rate=0.95)]),
            ValueError,
            r"names must differ; repeated: \['A'\]",
        ),
        (
            lambda: People(cohort=[Person("A", decay_rate=0.9), Person("B", sleep_half_hours=12)]),
            ValueError,
            r"same fields: 'A' gives \['decay_rate'\], 'B' gives \['sleep_half_hours'\]",
        ),
        (lambda: People(cohort=[Params()]), TypeError, "a cohort holds heartpole.people.Person values"),
        (
            lambda: People(cohort=[Person("A", decay_rate=0.9)], decay_rate=0.9),
            ValueError,
            "a cohort or per-field distributions, not both",
        ),
        (lambda: People.default().sample(np.random.default_rng(), -1), ValueError, "n must be an integer >= 0"),
    ],
)
def test_bad_populations_are_refused_clearly(make: object, error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        make()


def test_a_pair_given_as_a_list_is_a_pair() -> None:
    person = Person("Bo", wake_alertness=[0.6, 1.2])  # JSON gives lists
    assert person.values() == {"wake_alertness": (0.6, 1.2)}
    assert People(wake_alertness=[0.6, 1.2]).sample(np.random.default_rng(0), 2).values.tolist() == [
        [0.6, 1.2],
        [0.6, 1.2],
    ]
