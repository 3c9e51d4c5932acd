"""Campaigns of many runs: manifests, batch analysis, fits, the paper's reproduction."""

from .batch import Campaign, process_run, run_campaign, run_key
from .fits import LinearFit, campaign_fits, fit_line, summarize_lengths
from .manifest import RunSpec, read_manifest

__all__ = ["Campaign", "LinearFit", "RunSpec", "campaign_fits", "fit_line", "process_run", "read_manifest",
           "run_campaign", "run_key", "summarize_lengths"]
