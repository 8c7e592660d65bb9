"""The ground as found and as it yields: strata and the in-situ state (:mod:`.strata`,
:mod:`.loads`), groundwater and seepage (:mod:`.water`), and the constitutive laws as plain
functions of (trial stress, material) (:mod:`.mohr_coulomb`). The staged plastic driver that
takes a law as a callable is :mod:`solver.stages.plastic`."""
