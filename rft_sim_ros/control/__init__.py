"""The command path: servo/trajectory commands, validated and sampled in sim time."""
