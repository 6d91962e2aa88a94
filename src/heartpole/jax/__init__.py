"""HeartPole in JAX: a gymnax-compatible environment (``pip install 'heartpole[jax]'``).

::

    import jax
    from heartpole.jax import LegacyStep, evaluate, make

    env, params = make("HeartPole-v0")
    obs, state = env.reset(jax.random.key(0), params)
    obs, state, reward, terminated, truncated, info = env.step(jax.random.key(1), state, 2, params)
    result = evaluate("expert", episodes=2000)  # heartpole.evaluate's, played on the device
    legacy = LegacyStep(env)  # gymnax's older five-value step, for rejax: docs/rejax.md

``import heartpole`` never imports JAX; this package does.
"""

JAX_EXTRA = "pip install 'heartpole[jax]'"
"""How to install what this package needs."""

try:
    import jax  # noqa: F401
except ImportError as error:  # pragma: no cover - exercised in a subprocess without JAX
    raise ImportError(f"heartpole.jax needs JAX: {JAX_EXTRA}") from error

from heartpole.jax.env import EnvParams, EnvState, HeartPoleJax, make  # noqa: E402
from heartpole.jax.evaluation import evaluate, evaluate_batch  # noqa: E402
from heartpole.jax.legacy import LegacyStep  # noqa: E402
from heartpole.jax.spaces import Box, Discrete  # noqa: E402
from heartpole.jax.traced import MODEL, RNG  # noqa: E402

__all__ = [
    "Box",
    "Discrete",
    "EnvParams",
    "EnvState",
    "HeartPoleJax",
    "JAX_EXTRA",
    "LegacyStep",
    "MODEL",
    "RNG",
    "evaluate",
    "evaluate_batch",
    "make",
]
