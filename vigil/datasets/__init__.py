"""Real datasets loaded into canonical per-sequence arrays."""
