"""Image -> door pose: luminance, search region, sub-pixel edges, robust lines, corner, metric pose, quality gate."""
