"""Scenes: scene files (config), the paper's scenarios, robots, gaits and intruders."""
