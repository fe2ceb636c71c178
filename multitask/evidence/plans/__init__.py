"""Pre-registered plans: each read and checked, analysed, reported and designed (the fifth wing
of ``multitask.evidence``, after ``..studies``; ``..commands.plans`` holds their subcommands).

* ``confirm``: a pre-registered confirmatory analysis, run exactly as its plan file says (read
  first); ``exploratory``: the exploratory analyses its plan names, apart from its rows;
  ``confirm_report``: both written out, with ``confirm.md``, the outcome in the plan's words;
* ``design``: what the plan's folds x seeds could detect (variance shares, power);
* ``factors``: the factor study of ``results/tcn/PLAN_factors.md``: each level's validation
  scores against the baseline's, each outer fold's choice of setting;
* ``ladder``: its convergence ladders (section E): each pilot run's training loss checked as if
  its schedule had ended at each shorter length, and each backbone's length.

May import ``..runs``, ``..statistics``, ``..render`` and ``..studies`` (and ``multitask.grid``,
``multitask.models``, ``jigsaws_tools``, ``rnn_seg``); not ``..commands``; ``..studies`` does
not import this wing (``tests/test_packaging.py`` checks it).
"""
