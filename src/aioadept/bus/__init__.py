"""bus package of aioadept."""
