// Loaded before Leaflet: position tiles and markers with left/top instead of 3D transforms.
// Without a GPU (headless, remote desktops, many robot laptops) every translate3d element is
// its own composited layer; with hundreds of tiles and markers that halves the frame rate.
window.L_DISABLE_3D = true;
