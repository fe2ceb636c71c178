"""Command lines: the ``jigsaws-tools`` command and the conventions every command shares.

* ``main``: ``jigsaws-tools`` (inspect, stages, amendments, plot, synth);
* ``common``: ``--version``, ``-v``, quiet TensorFlow, one-line errors and exit codes, for every
  command of the project;
* ``arg_types``: range-checked option types; ``options``, ``task_options`` and
  ``format_options``: the options that choose a release, its task and its recording format.

May import the rest of ``jigsaws_tools``; nothing in ``jigsaws_tools`` outside this folder imports
it.
"""
