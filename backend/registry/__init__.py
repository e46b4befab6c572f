"""Model registry: versions, gate, rollout to robots, rollback, shadow mode."""
