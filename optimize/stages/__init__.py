"""The optimiser's stages, one module each with one entry point ``run(ctx, results) -> results``
(:data:`pamkin.optimize.pipeline.STAGES` declares their order), and the seed stage that prepares the design."""
