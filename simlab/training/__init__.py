"""Training and evaluation on tabular MDPs: harness, fused loops, ``simlab train``, curves and heat maps."""
