"""Instrument files into a :class:`harmonid.Dataset`: the importers of ``harmonid import``.

Every convention is a keyword without a default, so nothing is guessed:

- ``amplitude``: ``"peak"`` or ``"rms"`` (harmonid's amplitudes are peak; RMS is multiplied by √2);
- ``quadrature``: ``"x+iy"`` or ``"x-iy"`` (when the file's phase rises through a resonance);
- ``metres_per_unit``: metres of displacement per volt, or ``None`` to keep volts;
- ``response``: ``"displacement"`` (default), ``"velocity"`` or ``"acceleration"``.

Settling samples (``settle_s`` seconds into each step, or the first ``settle_samples``) are
dropped and counted in ``dataset.notes``. A sweep that turns back is cut into its passes
(``sweep_up``, ``sweep_down``, ``sweep_up_2``, ...), each an ordered sweep. Rows where nothing was
measured (every value NaN: a LabOne sweep stopped early) are dropped at a sweep's end with a
``UserWarning`` (also in ``dataset.notes``); inside a sweep they are refused with their row unless
``drop_nan_rows=True`` (``read_table``, ``read_zi_sweeper``). See ``docs/data-format.md``, "From your instrument to
a dataset", for each format's layout.

Example::

    import harmonid.io
    ds = harmonid.io.read_zi_csv(
        ["dev4955_demods_0_sample_00000.csv"], amplitude="rms", quadrature="x+iy",
        metres_per_unit=None, clockbase_hz=60e6, settle_s=0.5)
    ds.notes      # ["1 sweeps, 40 steps; 1600 of 8000 samples dropped as settling ..."]
"""

from ._harmonid import read_moku_csv, read_table, read_zi_csv, read_zi_hdf5, read_zi_sweeper

__all__ = ["read_moku_csv", "read_table", "read_zi_csv", "read_zi_hdf5", "read_zi_sweeper"]
