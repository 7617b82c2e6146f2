"""asv benchmark suites of rbbench (``asv.conf.json`` points here; see README, asv section).

``bench_hf``: the HF solve of ``rbbench solve``; ``bench_offline``: the offline stages
of ``rbbench reduce``; ``bench_online``: the online solve and the tracked accuracy of one
reduction. Shared cases and settings: ``_common``.
"""
