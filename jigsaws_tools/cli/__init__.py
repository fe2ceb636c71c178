"""Command lines: the ``jigsaws-tools`` command and the conventions every command shares.

* ``main``: ``jigsaws-tools`` (inspect, amendments, plot, synth);
* ``common``: ``--version``, ``-v``, quiet TensorFlow, one-line errors and exit codes, for every
  command of the project;
* ``arg_types``: range-checked option types; ``options`` and ``task_options``: the options that
  choose a release and its task.

May import the rest of ``jigsaws_tools``; nothing in ``jigsaws_tools`` outside this folder imports
it.
"""
