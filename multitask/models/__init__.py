"""The paper's models: what each variant learns and how one variant trains on one fold.

* ``variants``: the registry (A, APr, APc, APoc, Pr, Pc, Poc) and each variant's optimiser;
* ``heads``: the progress heads (regression, classification, ordered classification);
* ``gradnorm``: GradNorm's trainer; ``config``: loss weighting, GradNorm and head settings (no
  TensorFlow import);
* ``fold_run``: one variant on one LOUO fold (``train_variant``);
* ``run_record``: what a run's config.json records, written and read back checked (no
  TensorFlow import);
* ``time_baseline``: the time-only progress model (de Boer et al.), its per-fold scores on a
  release.

May import ``jigsaws_tools``, ``rnn_seg`` and ``baseline``; no other wing of ``multitask``.
"""
