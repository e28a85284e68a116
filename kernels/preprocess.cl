// Point-cloud pre-processing kernels (bilateral filter, normal estimation). Program "preprocess".
