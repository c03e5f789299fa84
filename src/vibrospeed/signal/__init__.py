"""Signal transforms with explicit state: pre-filters, spectra, differentiators, detectors."""
