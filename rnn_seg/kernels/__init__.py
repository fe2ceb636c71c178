"""Compiled kernels of the engine: the peephole LSTM's loops over time as TensorFlow custom ops.

``loops = "fused"`` (``EncoderConfig.loops``, ``--loops fused``) runs ``rnn_seg.lstm``'s forward
and backward loops as two C++ ops (``lstm_loops.cc``): each step's recurrent product streams
weights laid out once per call in panels, and the gate nonlinearities, peepholes and the chain
rule's per-step factors run inside the same pass, without TensorFlow's per-op dispatch. A third
op sums ``dW_h = h_prev^T dz`` over all steps where TensorFlow's own matmul would run Eigen's
contraction (its oneDNN operations off: ``rnn_seg.lstm.fused_weight_gradient``). The rest of
the layer (input product, dropout, resets, reversal, clipping) is unchanged.

* ``build``: compiles ``lstm_loops.cc`` on first use with the system C++ compiler (``g++``, or
  ``$CXX``) against the installed TensorFlow's headers, into
  ``~/.cache/mtrnn-jigsaws/kernels/tf-<version>/`` (``$JIGSAWS_CACHE_DIR``), and loads it; when it
  cannot, says why (``unavailable``) and the encoder runs the graph loops; a failed build is
  remembered, so later processes fall back at once;
* ``tether``: runs the compiler so that it ends with the process that started it;
* ``loops``: the two loop functions and the weight gradient ``rnn_seg.lstm`` calls for
  ``loops = "fused"``.

``python -m rnn_seg.kernels`` builds the library now (e.g. right after installing; it retries a
build that failed before) and prints where it is, or why it cannot be built (exit status 1).

Imports: TensorFlow, ``jigsaws_tools`` (the cache folder) and the engine's ``config`` only.
"""
