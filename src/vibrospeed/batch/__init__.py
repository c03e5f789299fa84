"""Many recordings at once: estimate each, resume, summarise; on local processes or Dask.

:func:`estimate_recording` is what ``vibrospeed estimate`` does for one recording (read, pick the
axis, run the method, write the estimate CSV and its JSON sidecar); :func:`run` does it for many
recordings, each in its own task, and returns the summary table (one row per recording):

=====================  ======================================================================
``file``               the recording (file, folder or zip) as given or found
``output``             its estimate CSV (``<name>_<method>.csv`` + ``.json``) in the output folder
``format``             the format it was read as
``duration_s``         its length in s
``method``             the estimator
``signal_share``       share of samples where the method saw a wheel line (``has_signal``; empty
                       for methods without it)
``median_speed``       median of the speed estimate in m/s (empty without a wheel radius)
``median_omega``       median of omega in rad/s
``distance_m``         integral of the speed over time in m; these three are empty where the
                       method says where it sees a line and nothing of the moving drive rests on
                       a measurement (:func:`drive_summary`)
``distance_lo_m``      the same integral of the speed band's lower / upper edge (``speed_lo``,
``distance_hi_m``      ``speed_hi``): the distance if every sample sat at that edge of its band
``fitted_radius``      wheel radius in m that the method fitted on this drive: ``fuse``'s learned
                       radius where the drive taught it (a wheel line while GPS was good; empty
                       where it kept its prior), :func:`vibrospeed.eval.metrics.radius_fit`
``fitted_radius_std``  its std in m; these two are present only when some row has a value
``status``             ``ok``, ``skipped`` (an up-to-date output was there) or ``error``
``error``              one line saying what went wrong
``note``               why numbers are empty (no wheel line or GPS while moving), and the note
                       ``vibrospeed estimate`` prints where the default wheel speed range was
                       searched (:func:`vibrospeed.estimators.params.range_note`), else empty
``wall_s``             seconds spent on this recording
``report``             its HTML report (only with ``report=True``)
=====================  ======================================================================

A recording is skipped when its estimate and sidecar exist and the sidecar records the same
method, options, vibrospeed version and input checksum (SHA-256 of the file or the folder's
files, and of the files read with it: :func:`vibrospeed.batch.single.read_with`). One bad
recording never stops the batch: its row says why. The work runs on a local process pool
(:mod:`concurrent.futures`, ``jobs`` processes) or, with ``scheduler`` (an address
``tcp://host:8786`` or a ``dask.distributed.Client``), on a Dask cluster; the workers must see
the same files (a shared file system) and have vibrospeed installed.

Example
-------
>>> from vibrospeed import batch                                    # doctest: +SKIP
>>> summary = batch.run(["logs/*.csv"], "out", method="grid", params={"omega_max": 60})
>>> summary[["file", "status", "median_speed", "distance_m"]]      # doctest: +SKIP

One concern per module, each importing only the ones above it:

===========  ==============================================================================
``single``   one recording as ``vibrospeed estimate`` does it (:class:`EstimateOptions`,
             :func:`load_recording`, :func:`estimate_recording`)
``inputs``   files, folders and patterns to recordings; unique output names
``task``     one batch task: skip when up to date, else estimate (and report); always a row
``pool``     the tasks on local processes or a Dask cluster, with a progress bar
``runner``   :func:`run`: the jobs, the summary table, ``summary.csv`` / ``.parquet``
===========  ==============================================================================
"""

from vibrospeed.batch.inputs import expand_inputs, output_names
from vibrospeed.batch.pool import default_jobs  # noqa: F401 (the module's names, as before)
from vibrospeed.batch.runner import (  # noqa: F401
    SUMMARY_COLUMNS,
    print_errors,
    run,
    write_summary,
)
from vibrospeed.batch.single import (  # noqa: F401
    Estimated,
    EstimateOptions,
    estimate_recording,
    load_recording,
    vibration_channel,
)
from vibrospeed.batch.task import drive_summary
from vibrospeed.eval.metrics import fitted_radius, track_summary  # noqa: F401 (re-exported)

__all__ = [
    "EstimateOptions",
    "Estimated",
    "SUMMARY_COLUMNS",
    "drive_summary",
    "estimate_recording",
    "expand_inputs",
    "load_recording",
    "output_names",
    "run",
    "track_summary",
]
