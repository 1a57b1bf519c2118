"""The numbers deformable sand's bed (`deformable`) and its compiled rules (`deformable_kernels`)
share: the indices of its small state vector and the rules' limits. Apart from both so that
each can import them (the bed calls the rules; the rules compile these in)."""

#: Rings (Chebyshev distance, nodes) searched around a committed node for the rim that
#: takes its sand before the distances of the step's committed nodes are found at once
#: (`deformable_kernels._free_distances`).
NEAR = 4
#: Node visits of the avalanche per step at most (the rest carries over to the next step).
MAX_VISITS = 200_000
#: A pair whose height difference exceeds the repose limit by less than this fraction of
#: the limit counts as settled (slopes end within 0.1 % of tan(repose)).
SETTLED = 1e-3

#: The small int64 state vector: pending count; the avalanche's work queue (first entry,
#: length); steps that ended with nodes still queued; dirty blocks listed; plates found in
#: the sand outside the bed (where they leave no footprint); the change epoch (counts the
#: steps that changed heights, and resets: `DeformableSand.blocks_changed_since`).
COUNT, HEAD, QUEUED, UNSETTLED, DIRTY, OUTSIDE, EPOCH = range(7)
STATE_SIZE = 7
