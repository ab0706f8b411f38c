"""The in-process policy options the ``--precision``/``--compile`` flags and the ``lerobot:`` spec options share,
apart from ``interface`` so that building ``indgen``'s parser imports no numpy."""

PRECISIONS = ("fp32", "bf16")  # bf16: the forward under torch.autocast
# torch.compile modes (policy_wrappers/compile.py)
COMPILE_MODES = ("off", "default", "reduce-overhead", "max-autotune")
CUDA_GRAPH_COMPILE_MODES = ("reduce-overhead",)  # CUDA graphs: nothing to capture on a CPU or MPS device
