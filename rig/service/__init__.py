"""``rig serve``: the rig as a service (docs/service.md): an HTTP API over a persistent queue of runs."""
