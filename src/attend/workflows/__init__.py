"""What `attend estimate` and `attend identify` do with files: read (:mod:`attend.io`), run the
estimator or the learner a model file describes (:mod:`attend.perception`), check the result.

- :func:`estimate_from_files`: the model file's estimator on a uniform, complete log
  (:mod:`.estimate`); :func:`has_gaps` and :func:`estimate_with_gaps`: on a log with missing
  values, skipped or jittered time stamps (:mod:`.estimate_gaps`);
- :func:`identify_from_files`: attend's learning (D, E, M steps) with the file's [learning]
  settings, and :func:`check_learned_model`: whether the learned model runs on the log
  (:mod:`.identify`);
- :func:`identify_nonlinear`: path-mode learning of a nonlinear model file's parameters
  (:mod:`.identify_nonlinear`).

Writing the results is :mod:`attend.io`'s (:func:`attend.io.write_estimates`,
:func:`attend.io.write_learned_model`, :func:`attend.io.write_learned_nonlinear`).

Example::

    from attend import io, workflows

    model = io.read_model("model.toml")
    log = io.read_log("log.csv", model.time_column)
    estimator, estimate = workflows.estimate_from_files(model, log)
    io.write_estimates("estimates.csv", log, model.system, estimate)
"""

from attend.workflows.estimate import estimate_from_files
from attend.workflows.estimate_gaps import estimate_with_gaps, has_gaps
from attend.workflows.identify import check_learned_model, identify_from_files
from attend.workflows.identify_nonlinear import identify_nonlinear

__all__ = [
    "check_learned_model", "estimate_from_files", "estimate_with_gaps", "has_gaps", "identify_from_files",
    "identify_nonlinear",
]

for _name in __all__:  # their public home: the API reference and pickles name attend.workflows
    globals()[_name].__module__ = __name__
del _name
