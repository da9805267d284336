"""Monte Carlo campaigns: hours of a suite's traffic with one controller, on this machine or a Dask cluster.

    from acc_gym.campaigns import run_campaign, load_campaign, summarise_campaign
    summary = run_campaign("singlelane-v3", hours=1.0, controller="acc", out_dir="runs/acc", workers=4)

(also ``acc-gym campaign --suite singlelane-v3 --hours 1 --controller acc --out runs/acc``).

* :mod:`~acc_gym.campaigns.plan`: which scenarios (index ``i`` of the suite's split, drawn
  from ``default_rng([i, root_seed])``), with which seeds, in which chunks;
* :mod:`~acc_gym.campaigns.episodes`: a worker runs one chunk and returns its rows;
* :mod:`~acc_gym.campaigns.backends`: this process, a local process pool, or Dask;
* :mod:`~acc_gym.campaigns.manifest`: the pinned settings (``campaign.json``);
* :mod:`~acc_gym.campaigns.store`: atomic, validated Parquet chunk files (resume, never count twice);
* :mod:`~acc_gym.campaigns.stats` and :mod:`~acc_gym.campaigns.summary`: paper 004's
  metrics with confidence intervals.

Needs ``pyarrow`` (``pip install 'acc-gym[campaign]'``) and, for Dask, ``pip install 'acc-gym[dist]'``.

Decisions (details in each module's docstring):

* **Root seed**: by default the split's own, so a campaign on ``test`` runs the suite's
  published test scenarios; another root draws scenario ``i`` by the same law from
  ``default_rng([i, root])``. Each episode's reset seed is the first draw of that generator.
  Nothing depends on the number of workers or the order chunks finish in.
* **Storage**: one Parquet file per chunk, written atomically by the driving process
  (workers return rows, so Dask workers need no shared filesystem). A chunk whose file
  exists and validates is never run again; a file that does not validate is an error
  naming it (to be deleted by hand), never silently re-run or read as empty -- atomic
  writes mean a kill cannot produce one, so it signals damage worth a look.
* **Checksums**: each chunk's sha256 is written beside it (``chunk-NNNNNN.sha256``, before
  the chunk) and recorded in ``campaign.json`` (``chunk_sha256``, the manifest rewritten
  atomically after each chunk); a chunk whose bytes, ``.sha256`` file and record disagree
  is refused by name. The file beside the chunk is what survives a lost manifest.
* **A lost manifest**: a missing or unreadable ``campaign.json`` is rebuilt by running the
  campaign again with its settings: the chunk files that verify against them (checksum,
  fingerprint, chunk number, rows) are kept and the rest run; one that does not verify is
  refused by name, nothing deleted. Campaigns of older acc-gym versions (no code digest
  or checksums) are refused saying so: run them again in a new directory.
* **Settings**: pinned in ``campaign.json``; resuming with other settings is an error
  naming each difference (except more ``hours``, which extend the campaign in place).
* **Dependencies**: pyarrow is an extra (``campaign``), not core: the simulator, the
  environments and training do not need it; the ``test`` and ``all`` extras include it
  and Dask. ``acc-gym campaign`` says what to install when either is missing.
* **UN R157**: each collision's row says whether it was ``preventable`` (``cc-driver``, the
  careful and competent driver, avoids the same scenario with the same seed; re-driven in
  the worker, collided episodes only) and the summary counts ``preventable_collisions`` and
  ``non_preventable_collisions``; the column made the campaign format ``acc_gym.campaign/2``.
* **Statistics**: deterministic intervals (exact Poisson, Wilson, Student t, a
  cluster-robust pooled share), so a summary is a pure function of the rows.
"""

from acc_gym.campaigns.campaign import Campaign, load_campaign, run_campaign
from acc_gym.campaigns.errors import CampaignError, MissingDependencyError
from acc_gym.campaigns.plan import scenario_at, seed_for
from acc_gym.campaigns.summary import format_summary, load_summary, summarise_campaign

__all__ = ["Campaign", "CampaignError", "MissingDependencyError", "format_summary", "load_campaign", "load_summary",
           "run_campaign", "scenario_at", "seed_for", "summarise_campaign"]
