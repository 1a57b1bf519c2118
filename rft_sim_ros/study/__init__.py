"""Studies: many runs of one scene over varied values, on all local cores or a Ray cluster.

`spec` loads and expands study files into runs; `execute` is one run in a worker; `pool` (local
processes, the default) and `ray_backend` (optional) run them and stream outcomes back;
`sweep.run_study` records each run, resumes, and writes the results table (`table`),
plots (`plots`) and the study's pages (`page`). `rft-sim sweep STUDY.yaml` is the command; docs/studies.md the guide.
"""
from .spec import Study, StudyError, load_study, study_from_mapping
from .sweep import StudyResult, run_study

__all__ = ['Study', 'StudyError', 'StudyResult', 'load_study', 'run_study',
           'study_from_mapping']
