"""``python -m agents.train``: PPO training entry point (see agents/ppo.py)."""

from agents.ppo import main, train

__all__ = ["main", "train"]

if __name__ == "__main__":
    main()
