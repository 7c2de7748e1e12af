// Builds the viewer page (web/) into dist/, which is committed and compiled into the toonforce
// binary (cmake/embed_assets.cmake). Deterministic for the locked versions (package-lock.json):
// .ci/run rebuilds and compares with the committed dist/ (scripts/check-dist.mjs).
import { defineConfig } from 'vite';

export default defineConfig({
  root: 'web',
  base: '/',
  logLevel: 'warn',
  build: {
    outDir: '../dist',
    emptyOutDir: true,
    assetsInlineLimit: 0,
    chunkSizeWarningLimit: 2000,
    reportCompressedSize: false,
    sourcemap: false,
    target: 'es2022',
  },
});
