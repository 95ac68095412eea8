"""What a real camera does to a straight black-white edge, measured on chessboard photographs.

The board is the reference: each square edge lies on the line (through the distortion) between two inner
corners. :mod:`~doorloc.photometric.board_edges` places the edges and measures their offsets,
:mod:`~doorloc.photometric.model` is the camera's photometric model, :mod:`~doorloc.photometric.catalogue`
names the causes, :mod:`~doorloc.photometric.fit` fits and chooses them by photographs held out,
:mod:`~doorloc.photometric.profiles` fits the edges' profiles, :mod:`~doorloc.photometric.twin` renders each
photograph's twin that a profile misfit is judged against, :mod:`~doorloc.photometric.check` runs the whole
check and :mod:`~doorloc.photometric.report` writes it.
"""
