"""The staged solve of one case on a built :class:`~solver.model.TunnelModel`, as an engineer
reads it: the loads of each stage (:mod:`.loads`: in-situ state released, lining weight, water,
seepage), the contact stage (:mod:`.contact`: loads solved forward to interface jumps, the contact
problem of the case's interface model), its recovery and checks (:mod:`.recovery`), and the
order of it all (:mod:`.solve`). The state passed between them is in :mod:`.state`."""
