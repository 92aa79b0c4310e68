"""apps package of aioadept."""
