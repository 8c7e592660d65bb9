"""Finite elements of the bodies: assembly of plane-strain P2 elasticity on scikit-fem
(:mod:`.assembly`), sparse Cholesky factorizations and orderings (:mod:`.linalg`), and the
factorized bodies seen from the interface (:mod:`.flexibility`: ``B K⁺ Bᵀ``)."""
