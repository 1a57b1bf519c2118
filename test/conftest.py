"""Test configuration: reproducible property tests.

Hypothesis draws the same examples on every run (derandomize), so CI is deterministic; set
HYPOTHESIS_PROFILE=explore for a long randomised search when changing the force law.
"""
import os

from hypothesis import settings

settings.register_profile('default', max_examples=200, derandomize=True, deadline=None)
settings.register_profile('explore', max_examples=5000, deadline=None)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'default'))
