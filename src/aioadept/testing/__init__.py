"""testing package of aioadept."""
