"""A small cohort the tests of oracle regret share (three solves, cached on disk after the first run).

Ada is v0 (Ada's rule is ``optimal``'s); Bo sleeps 6 hours and wakes dull; Max sleeps 10 hours and wakes
bright. Their optimal sleep timings differ enough to measure: Ada's rule costs Bo about 0.002 and Max about
0.019 of expected return (2,000 episodes each, seed 0), so an oracle that ignored the person would have an
oracle regret near 0.007, where 2,000 episodes give intervals about +-0.0004 wide.
"""

from __future__ import annotations

from heartpole.people import People, Person

TRIO = People(
    cohort=[
        Person("Ada", sleep_half_hours=16, wake_alertness=(0.7, 1.3)),
        Person("Bo", sleep_half_hours=12, wake_alertness=(0.5, 0.9)),
        Person("Max", sleep_half_hours=20, wake_alertness=(1.6, 2.4)),
    ]
)
