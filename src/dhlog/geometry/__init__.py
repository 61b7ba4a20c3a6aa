"""Pure geometry: lines, planes, fits. numpy/scipy only; no I/O."""
