"""Run folders you can trust: what a run owns, and the checks that keep a folder and its
weights in step.

* ``folder``: strict-JSON atomic writes, configuration to and from JSON, the files a run owns,
  its checkpoints' sweeps, the finished-run marker;
* ``settings``: what a folder is checked against (the settings hash);
* ``checkpoints``: save, fall back, prune, ``restore_weights``;
* ``logs``: the per-unit CSV logs (``history.csv``), a fixed column set, repaired at resume;
* ``tracking``: finished runs logged to MLflow (optional; MLflow imported only there);
* ``outputs``: where a command may write (never over a run or a grid); ``publish``: an output
  replaced all or nothing (a folder swapped whole, or journalled moves the next call finishes);
  ``manifest``: a command's files in a folder it shares (all at once, listed, never over yours);
* ``lock``: one writer per folder; ``provenance``: where a result came from;
  ``timing``: seconds per phase (``timing.json``).

May import ``rnn_seg.config``, ``rnn_seg.validation`` and ``jigsaws_tools``; TensorFlow only
inside ``checkpoints``. The rest of the engine imports this folder, never the reverse.
"""
