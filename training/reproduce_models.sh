#!/usr/bin/env bash
# Rebuild the bundled models and every figure of assets/models/README.md, step by step.
#
#   bash training/reproduce_models.sh STEP...      (steps run in the order given)
#
# The bundled models (issue 16; "all" runs these in order): data-v2, then normals-v2 normals8-v2
#   mesh-v2 silhouette-v2 (the four trainings run side by side, one thread each), then joint-v2
#   export-v2 eval-v2 eval-strong-v2 eval-side-v2 eval-gt-v2 tradeoff-v2 gallery-v2 compare-v2 ship-v2 refine-v2 docs-v2.
# The third bundled models (all-gpu): trained on a lent GPU by training/gpu_lease.sh, then fetch-gpu
#   (GPU_FILES, GPU_BASIS) and the steps from joint-v2 on, with RUNS2=runs/gpu OUT2=out/v3.
# The fourth bundled models (all-v4): the third's predictor continued on the generator's own normal images of
#   the training sketches (generated-v4 predictor-v4), evaluated, exported and shipped into OUT4 [out/v4].
# Trials after the fourth (trials-v5, into OUT5 [out/v5]; nothing shipped): the fourth's predictor continued on two
#   generated sets (a second drawing of every view: another seed, full-strength augmentation) and with doubled fully
#   connected layers, each against continuing it unchanged (generated-v5 predictor-v5 logs-v5 eval-*-v5 eval-train-v5).
# The surface measure of voxel IoU (remeasure-v6, into OUT6 [out/v6]): the headline figures again, with the cells a
#   thin part's surface passes through counted (eval-v6 eval-strong-v6 eval-side-v6 eval-gt-v6 eval-train-v6 compare-v6
#   refine-v6 thin-v6 variety-v6 fit-v6);
#   deep-v6: a deeper encoder against trials-v5's control (predictor-v6 logs-v6 eval-deep-*-v6); interior-v6: the full
#   loss with the normal term's gradient kept off the outline (full-interior-v6 full-interior-x5-v6 eval-interior-*-v6).
# The fifth bundled models (all-v7, into OUT7 [out/v7]): interior-v6's predictor trained on (predictor-v7), chosen
#   against it and the fourth on the validation split (val-v7), evaluated, exported, timed and shipped (eval-*-v7
#   eval-train-v7 export-v7 tradeoff-v7 gallery-v2 compare-v7 ship-v2 refine-v2 docs-v2), surface measure; then its
#   silhouette-only control trained as long (control-v7 logs-v7 eval-control-*-v7).
# The sixth candidate (fresh-v8, into RUNS8 [runs/v8] and OUT8 [out/v8]; needs nothing but this repository): the fifth
#   pair taken from git and imported back as training runs (models-fifth-v8 generated-v8 import-v8), its predictor trained
#   on as it is and with mirrored items at equal time (predictor-v8 mirror-check-v8) and measured against it (val-v8
#   eval-v8 eval-strong-v8 eval-side-v8 eval-gt-v8), the plain run trained on (predictor-v8-more val-v8-more), their logs (logs-v8); all-v8
#   then measures, exports, times and ships it (eval-*-v8b export-v8 tradeoff-v8 gallery-v2 compare-v8 ship-v2
#   refine-v2 docs-v2, into OUT8/final).
# The seventh candidate (fresh-v9 after fresh-v8 and predictor-v8-more, into RUNS9 [runs/v9] and OUT9 [out/v9]): the
#   generator's images of the mirrored drawings (generated-mirror-v9), the sixth predictor (v8_more2) trained on as
#   it is and with half of every batch mirrored from those exact inputs at equal time (predictor-v9), chosen on the
#   validation split (val-v9), measured (eval-v9 eval-strong-v9 eval-side-v9 eval-gt-v9 logs-v9); all-v9 then exports,
#   times and ships it (float32 predictor) (export-v9 tradeoff-v9 gallery-v2 compare-v9 ship-v2 refine-v2 docs-v2, into OUT9/final).
# The eighth candidate (fresh-v10 after fresh-v9, into RUNS10 [runs/v10] and OUT10 [out/v10]): the seventh predictor
#   continued on a lent GPU at batch 512 on true normal images (training/gpu_predictor.sh; fetch-gpu-v10, checked on
#   the validation split's true normal images by val-gpu-v10), then fine-tuned here on the generator's images against
#   the seventh fine-tuned as long without the GPU stage (predictor-v10), chosen on the validation split (val-*-v10),
#   measured (eval-*-v10 logs-v10); all-v10 exports, times and ships it (export-v10 tradeoff-v10 gallery-v2
#   compare-v10 ship-v2 refine-v2 docs-v2, into OUT10/final).
# The tenth candidate (fresh-v11 after fresh-v10 and all-v10-more, into RUNS11 [runs/v11] and OUT11 [out/v11]): the ninth
#   predictor continued on a lent GPU (gpucarry-v11, then training/gpu_predictor.sh; fetch-gpu-v11, val-gpu-v11), then
#   fine-tuned here on the generator's images against the ninth fine-tuned as long without it (predictor-v11), chosen on
#   the validation split (val-*-v11), measured (eval-*-v11 logs-v11); all-v11 exports, times and ships it; all-v11-more
#   trains it on alone (predictor-v11-more), checks it on the validation split, and measures and ships it likewise.
# A larger predictor from the start (into RUNS12 [runs/v12] and OUT12 [out/v12]): trained on a lent GPU from scratch
#   (training/gpu_predictor.sh fresh with ARCH; fetch-gpu-v12), checked on the validation split's true normal images
#   against the ninth's GPU stage (val-gpu-v12), fine-tuned here on the generator's images (predictor-v12), chosen on
#   the validation split (val-*-v12) against the ninth and the ninth fine-tuned 10,000 iterations more, measured
#   (eval-*-v12 logs-v12) (fresh-v12); all-v12 exports, times and ships it.
# Mirror averaging (mirror-v13, into OUT13 [out/v13]; needs runs/v10/v10_more and runs/v12/v12_more2): every mesh
#   averaged with the one predicted from the drawing flipped left to right, checked on the validation split
#   (val-*-mirror-v13, val624-mirror-v13) before the test split (eval-*-mirror-v13), timed in the app's engine
#   (cost-v13), scored in the app's own path (compare-v13), against run time (tradeoff-v13), under refinement
#   (refine-v13), pictured (gallery-v13) and put in the README (docs-v13). Mirror averaging learned (into RUNS13
#   [runs/v13]): the ninth trained on with and without the mirror-consistency term at equal time (predictor-v13
#   logs-v13), compared plain and averaged on the validation split (val-*-v13).
# The larger predictor trained on with the mirror-consistency term (into RUNS14 [runs/v14] and OUT14 [out/v14]; needs
#   runs/v13/v13_big_mc): predictor-v14-big, checked against the ninth on the validation split (val-*-v14-big).
#   What the outline refinement costs in 3D through its estimated camera (refine-oracle-v14, a diagnostic).
# The eleventh pair (into RUNS14 and OUT15 [out/v15]; needs runs/v14/v14_big_mc): the tenth trained on with five times
#   the dihedral weight against the folds (predictor-v15-fold) and, at equal cost, with the paper's weight
#   (predictor-v15-control), compared on the validation split (val-*-v15-all, folds-v15, folds-v15-control; the choice
#   in OUT14/fold/choice.txt); all-v15 measures, exports, times and ships the control (eval-*-v15 export-v15 cost-v15
#   tradeoff-v15 compare-v15 ship-v15 refine-v15 repair-v15 gallery-v15 docs-v2).
# Is the basis damping holding back detail? (into RUNS16 [runs/v16] and OUT16 [out/v16]; needs runs/v14/v15_control):
#   the eleventh trained on side by side, one thread each, re-smoothed to a damping of V16_SMOOTH [4] instead of 16
#   (predictor-v16-smooth, the same function at the start) and unchanged (predictor-v16-control), both by train7's
#   recipe for V16_ITERS [3000] iterations (predictor-v16 runs both); compared on the validation split
#   (val-*-v16, folds-v16-*) and pictured (gallery-v16). Then the other way, damping 64, and the control's recipe at a
#   quarter of the rate (predictor-v16b: predictor-v16-damp64, predictor-v16-lowlr; val-*-v16b against v16_control).
#   All level on validation. The aligned branch (the image sampled where each vertex lands) added to v16_control and
#   trained on against an equal-cost control (predictor-v16c: predictor-v16-aligned, predictor-v16-control2; val-*-v16c).
#   predictor-v17 trains v16_aligned on along one long cosine, a sitting at a time; val-*-v17 sets it beside the eleventh
#   and the trial's control on the validation split; all-v17 measures, exports, times and ships it as the twelfth pair
#   (into OUT17 [out/v17]: eval-*-v17 export-v17 cost-v17 tradeoff-v17 compare-v17 ship-v17 refine-v17 repair-v17
#   gallery-v17 docs-v2; session-v17 after it). predictor-v17-control trains the branchless control as long.
# The thirteenth candidate from a fresh clone (fresh-v18, into RUNS18 [runs/v18] and OUT18 [out/v18]; needs nothing but
#   this repository): the dataset and the generator's images (data-v2 generated-v8 generated-mirror-v9 import-v8), the
#   twelfth pair from git (models-twelfth-v18) imported back as a training run (import-v18), its predictor trained on
#   by the twelfth's recipe along a new cosine (predictor-v18), set against it on the validation split (val-*-v18,
#   logs-v18); all-v18 measures, exports, times and ships it like all-v17 (into OUT18/final).
# The fourteenth candidate (after fresh-v18, into RUNS19 [runs/v19] and OUT19 [out/v19]): the direct fit from a template
#   with legs (fit-legs-v19); the thirteenth predictor continued on a lent GPU at batch 512 on the generator's images
#   (gpucarry-v19, training/gpu_predictor.sh, fetch-gpu-v19), set against it on the validation split (val-*-v19,
#   logs-v19), then trained on here at batch 32 and at batch 128 side by side (predictor-v19, val-*-v19b); all-v19
#   measures, exports, times and ships the chosen run (V19_RUN [g19]) like all-v18 (into OUT19/final).
# The fifteenth candidate (into RUNS20 [runs/v20] and OUT20 [out/v20]): the predictor generalises worse than it fits
#   (train split 0.630, val 0.563: overfit-v20), so twice the shapes: DATA20 [data/proc200e4], 200 per category, the
#   first 100 those of DATA2 (data-v20; the generator's images of its train split: generated-v20, generated-mirror-v20),
#   the fourteenth predictor trained on it by predictor-v19's batch-32 recipe (predictor-v20, against v19_b32: the same
#   start, schedule and samples on DATA2), set against both on DATA2's validation split (val-*-v20, logs-v20); all-v20
#   measures, exports, times and ships it like all-v19 (into OUT20/final), retrieval-*-v20 the retrieval floor from
#   DATA20's train split on the same test samples, session-v20 the app under the pen.
# The sixteenth candidate (into OUT21 [out/v21]): the fifteenth predictor trained on along a new cosine on DATA20
#   (predictor-v20-more, into RUNS20/v20_more), set against it on the validation split (val-*-v20-more, logs-v21, overfit-v21); all-v21
#   measures, exports, times and ships it like all-v20 (into OUT21/final; its retrieval floor is retrieval-*-v20's,
#   the same shapes and samples), cost-both-v21 times it beside the fifteenth's files, session-v21 the app under the pen.
#   predictor-v21-more trains it on by the same recipe (into RUNS20/v21_more), val-*-v21-more sets that against it.
# The seventeenth candidate's GPU stage (into RUNS22 [runs/v22] and OUT22 [out/v22]): the sixteenth predictor as bundled
#   (imported from assets/models there) trained at batch 512 on a lent H100 on DATA20's 2,087 training shapes at 24 views
#   each (training/gpu_predictor.sh SHAPES=200 VIEWS=8 ELEVATIONS="0 20 40", in its header), brought back by
#   fetch-gpu-v22 (RUNS22/g22) and set against the sixteenth on the validation split (val-*-v22-gpu).
#   views-v22 measured why it lost (it moved to its off-grid views). The seventeenth candidate itself (into OUT22): the
#   sixteenth trained 5,000 more iterations on the CPU (predictor-v21-more, RUNS20/v21_more), chosen on the validation
#   split (val-*-v21-more, out/v22/choice.txt); all-v22 measures, exports, times and ships it like all-v21, cost-both-v22
#   times it beside the sixteenth's files, session-v22 the app under the pen, logs-v22 and overfit-v22 its training.
#   predictor-v22-more trains it on by the same recipe (into RUNS20/v22_more), val-*-v22-more sets that against it.
# The next data (DATA30 [data/proc300e4]): 300 shapes per category, DATA20's files linked in (data-v23), and the
#   generator's images of its train split (generated-v23, generated-mirror-v23: DATA20's rows copied for its shapes),
#   for a predictor on three times DATA2:
#   predictor-v23 (the seventeenth on it, into RUNS23 [runs/v23]), val-*-v23 (into OUT23 [out/v23]). The eighteenth
#   candidate, if it is chosen there (out/v23/choice.txt): all-v23 measures, exports, times and ships it like all-v22,
#   retrieval-*-v23 the retrieval floor from DATA30's train split, cost-both-v23 times it beside the seventeenth's
#   files, session-v23 the app under the pen, logs-v23 and overfit-v23 its training.
# The data after it (DATA40 [data/proc400e4]): 400 shapes per category, DATA30's files linked in (data-v24), and the
#   generator's images of its train split (generated-v24, generated-mirror-v24: DATA30's rows copied for its shapes);
#   predictor-v24 trains the eighteenth on it (into RUNS24 [runs/v24]), val-*-v24 sets it against the eighteenth (OUT24 [out/v24]).
#   The nineteenth candidate, if it is chosen there (out/v24/choice.txt): all-v24, retrieval-*-v24 (from DATA40),
#   cost-both-v24, session-v24, logs-v24 and overfit-v24, as for the eighteenth.
# A lent GPU (gpu_predictor.sh's header: the bundled pair on 600 shapes per category, 4 of the 48 grid views each, in
#   two calls from the twentieth, g25 then g25b): fetch-gpu-v25 places each call's files in RUNS25 [runs/v25],
#   val-*-v25-gpu sets them against the twentieth (OUT25 [out/v25]).
# On the CPU meanwhile: predictor-v24-more trains the nineteenth a second pass over DATA40 (into RUNS24/v24_more),
#   average-v25 averages the two (RUNS24/v25_swa), val-*-v24-more sets both against the nineteenth (OUT25/val_more_*).
#   The twentieth candidate, chosen there (out/v25/choice.txt: v24_more): all-v25, cost-both-v25, session-v25, logs-v25
#   and overfit-v25 (its retrieval floor is retrieval-*-v24's: the same data). predictor-v25-more trains it a third pass
#   (RUNS24/v25_more), val-*-v25-more sets that against it (OUT25/val_third_*).
# The twenty-first candidate, the GPU stage's g25b (chosen over the twentieth on validation: out/v26/choice.txt): all-v26,
#   cost-both-v26, session-v26, logs-v26 and overfit-v26 into OUT26 [out/v26] (its retrieval floor is still DATA40's:
#   the 600-shape data it trained on was built on the lent machine only).
# A CPU pass on shapes the twenty-first never saw (no GPU lent, 2026-11-28): data-v27 renders DATA70 [data/fresh600v4]
#   (shapes 600-1199 of each category, the train split, 4 views each), generated-v27 and generated-mirror-v27 the
#   generator's images of them, import-v27 the twenty-first back from git as a run (RUNS27 [runs/v27]),
#   predictor-v27 trains it on them, val-*-v27 sets the run against its start (OUT27 [out/v27]).
#   Then (2026-11-28, a second session): data-v27-check renders DATA72 [data/check1200v4] (shapes 1200-1249, a second
#   validation set nothing trained on or was chosen by) and check-*-v27 scores the twenty-first and the three CPU
#   passes on it; eval-big-*-v27 the bundled twenty-first on ten times eval-*-v26's test sketches; control-v27 and
#   eval-control-*-v27 full minus silhouette-only over predictor-v27-low's continuation.
# The end-to-end fine-tune of the twenty-first pair (2026-11-28, a third session; no GPU lent): joint-pilot-v28 sets
#   the generator's rate and the mesh loss's weight on DATA72 (260 strongly augmented sketches), joint-v28 fine-tunes
#   the fifth generator through the twenty-first predictor held fixed (`train joint --freeze-predictor`) on DATA70
#   into RUNS28 [runs/v28], check-*-v28 sets it against the twenty-first pair on DATA72 (OUT28 [out/v28]).
#   generated-*-v28-strong draw DATA70's generated sets from strongly augmented drawings (1.0, the strong case's; so far
#   0.5), predictor-v28-strong trains the twenty-first on them as predictor-v27-low did on the 0.5 sets, and
#   check-*-v28-strong sets the two passes against the twenty-first on DATA72.
# The app's two input paths (2026-11-28, a fourth session; no GPU lent): eval-{canvas,image}[-strong|-side]-v29 score the
#   bundled pair on every test sketch as the app's canvas (strokes framed at the standard width in full ink) and its
#   image-file path feed the generator (`eval --sketch-path`), where eval-full-*-v27 fed the stored rasters (OUT29 [out/v29]).
#   check-scale-*-v29 and eval-scale-v29 probe a calibration: the meshes scaled by 0.98 before scoring (`eval --mesh-scale`).
# A weight soup (2026-11-28, a fifth session; no GPU lent): soup-v30 averages the twenty-first predictor and its three
#   CPU passes on DATA70 into RUNS30 [runs/v30], check-soup-*-v30 sets the soups against the twenty-first on DATA72 and
#   eval-soup-*-v30 on every test sketch (OUT30 [out/v30]). Level mirror averaged on the test split: nothing shipped.
# The direct fit's damping (2026-11-28, a sixth session; no GPU lent): fit-damping-v31 fits the first training shape of
#   every category at the large-steps damping 2, 4, 8 and 16 (bench fit's default was 16); overfit-v31 is issue 14's
#   overfit check (the predictor on 13 training shapes, one per category, 20 min) against fits at damping 4, and
#   overfit-damping-v31 the same with the predictor's own basis damped at 4; overfit-table-v31 on one table alone;
#   overfit-views-v31 on twelve shapes at the training elevations (OUT31 [out/v31]).
# What the table lacks among other shapes (2026-11-28, a seventh session; no GPU lent): overfit-table310-v32 trains the
#   table alone for the samples it gets among 13 shapes; overfit-b8-v32, overfit-lr-v32, overfit-long-v32 and
#   overfit-seed-v32 are overfit-v31 at batch 8, at twice the rate, for twice the time and with a second seed,
#   overfit-long-seed-v32 the 40 minutes with the second seed;
#   compare-overfit-v32 sets them side by side at equal wall-clock time (OUT32 [out/v32]).
# Samples or steps at the GPU's batch (2026-11-28, an eighth session; no GPU lent): overfit-b512-v33 and overfit-b128-v33
#   are overfit-v31 at batch 512 and 128 for the same samples, overfit-b512-lr-v33 at 512 with four times the rate,
#   overfit-b256-v33 at 256, overfit-b128-long-v33 overfit-long-v32 at 128;
#   compare-overfit-v33 sets them beside overfit-v31 run again on this machine (OUT33 [out/v33]).
# What the normal term adds where the silhouettes cannot carve (2026-11-28, a ninth session; no GPU lent):
#   overfit-sil-v34 is overfit-v31 silhouette-only (lambda_n 0); overfit-single-v34 and overfit-single-sil-v34 are
#   overfit-v31 and its silhouette-only twin supervised from the input view alone (extra_views 0: no other view's
#   outline); compare-single-v34 sets the four side by side (OUT34 [out/v34]). overfit-interior-v34 is overfit-v31 with
#   the normal term's gradient kept off the outline (--no-normal-edges, as every bundled predictor since the fifth
#   trains); compare-interior-v34 sets it beside overfit-v31 and overfit-sil-v34; variants-normal-v34 trains the three
#   (and the term off the outline at five times its weight) from the start on DATA's training shapes for the same 2,000
#   iterations and scores them on its test shapes;
#   eval-normal-v34 exports the four beside the bundled generator and scores them from sketches as the app runs them.
# Does the normal term's gain grow with the shapes? (2026-11-29, a tenth session; no GPU lent): data100-v35 renders
#   DATA100's 100 shapes per category as DATA renders 30 (the same generator draws the same shape for a category and
#   index, and the split is a hash of them: DATA's test shapes are DATA100's too); variants-data-v35 trains
#   variants-normal-v34's full-interior, silhouette-only and full-interior-x5 on it for the same 2,000 iterations;
#   eval-data-v35 scores those three and variants-normal-v34's from DATA100's test drawings as the app runs them
#   (OUT35 [out/v35]); variants-data-long-v35 and eval-data-long-v35 are full-interior and silhouette-only trained on
#   DATA100 twice as long (4,000 iterations) and scored the same ways.
#   eval-gt-data-v35 scores variants-normal-v34's and variants-data-v35's predictors on the same 520 test views' true
#   normal images (the 100-shape ones as variants-data-v35 scored them: a check of that table).
#   gen-inputs-v35 runs the bundled generator over DATA's training drawings (the inputs the app feeds the predictor);
#   variants-gen-v35 trains full-interior and silhouette-only from the start reading them, and eval-gen-v35 scores
#   those two as eval-data-v35 scores its (does the normal term add more when the predictor reads what the app feeds it?).
#   gallery-data-v35 draws variants-data-long-v35's two predictors' meshes from the same test drawings, side by side.
#   variants-views-v35 and eval-views-v35: full-interior and silhouette-only with one other view in the loss instead of
#   three (extra_views 1: the silhouettes carve less of the depth), trained and scored as variants-normal-v34's.
# A specialist for the legged furniture (issue 16's parts target; legs-v36 runs these in order, into RUNS36 [runs/v36],
#   OUT36 [out/v36]; nothing shipped unless it says so): data-v36 renders DATA36 [data/legs600v4] (bench, chair and table
#   shapes 600-1199, their train split at 4 grid views each, as DATA70), DATA36C [data/legs1200v4] (shapes 1200-1249 of
#   the three, as DATA72: the choice) and DATA36T [data/legs100e4] (DATA2's shapes of the three, val and test splits);
#   generated-v36 / generated-mirror-v36 the fifth generator's images of DATA36's drawings; import-v36 the twenty-first
#   pair from git, its predictor as a run; predictor-v36-legs trains that predictor on the three categories alone (the
#   CPU recipe at V36_LR [2e-4], V36_ITERS [3000], V36_MINUTES [65] at most; resumes); export-v36 writes it beside the
#   bundled generator; check-legs-v36 scores both pairs on DATA36C through the app's engine (mirror averaged too), and
#   eval-legs-v36 / eval-legs-side-v36 on DATA36T's test split; gallery-legs-v36 draws both pairs' meshes of the same
#   test drawings: do the legs come with a category's samples? legs-more-v36 (after it): predictor-v36-legs-more trains
#   the specialist on as long again (export-v36-more), and the measures run again with it beside the two.
#   route-v36: how often the category of the nearest training drawing (a router's first candidate) says legged exactly
#   when a test drawing is (DATA36L [data/lib1200v4], DATA36A [data/test100e4]), and the 13-category mean on those
#   drawings with the specialist behind that router (and routed perfectly, a ceiling).
# A router for the specialist (issue 16; RUNS37 [runs/v37], OUT37 [out/v37]): data-v37 renders DATA37 [data/route1300v4]
#   (shapes 1300-1549 of all 13 categories, train split, 4 grid views each) and the fifth generator's images of its
#   drawings and of DATA36L's; router-v37 trains the category router on them (`sketchmesh router train`) and scores it on
#   DATA36L; routed-v37 puts the bundled pair, legs-more-v36's specialist and the router in one model folder;
#   eval-route-{clean,side,strong}-v37 score that folder beside the bundled pair on every test sketch of the case as the
#   app runs them; gallery-route-v37 draws both folders' meshes of the same test drawings; latency-route-v37 times the
#   app's path with each folder (route-all-v37 runs these seven in order).
#   predictor-v37-legs-more2 trains the specialist on a third time as long; check-legs-v37 scores it on DATA36C (the
#   choice); routed2-v37 puts it in the routed folder and eval-route2-*-v37 score that folder on the same test drawings;
#   ship-v37 bundles it (the bundled specialist since 2026-11-29 09:00; OUT37/models_routed's was bundled first).
# A wider router (the thirty-fifth bundle; RUNS55 [runs/v55], OUT55 [out/v55]; router-v55-all runs the first twelve in
#   order): bundle34-v55 takes the thirty-fourth bundle from git; eval-bundle-{clean,side,strong}-v55 score it on every
#   test sketch; only-{legs,second,third}-<case>-v55 score each specialist alone on its categories' test drawings, and
#   oracle-<case>-v55 what a perfect router would add; data-v55 and data-strong-v55 rebuild the router's drawings (DATA37,
#   DATA36L) with the generator's images of clean, flipped and strongly augmented drawings; router-v55 trains a router
#   twice as wide on them; routed-v55 exports it on the bundle and tables both routers by threshold on DATA36L;
#   eval-router-{clean,side,strong}-v55 score it; ship-router-v55 bundles it; latency-bundle34-v55, latency-bundle-v55,
#   tradeoff-bundle-v55, router-cost-v55 time it, docs-v55 draws the README's gallery and plot.
# Mirror routing (OUT56 [out/v56]; mirror-v56-all runs the measuring steps in order): bundle35-v56 takes the thirty-fifth
#   bundle from git; data-val-v56 renders the router's validation drawings (DATA36L) and the generator's images of them
#   plain and flipped; mirror-v56 sets route_mirror on a copy of the bundle (sketchmesh router set: the router reads the
#   drawing and its flip, which the app's mirror averaging computes anyway, and routes on their mean probabilities) and
#   tables both ways on DATA36L; eval-bundle-{clean,side,strong}-v56 and eval-mirror-{clean,side,strong}-v56 score both
#   on every test sketch, paired; mirror06-v56 and eval-mirror06-{clean,side,strong}-v56 the same at the threshold
#   the validation table favours for it (0.6), plain06-v56 and eval-plain06-*-v56 that threshold without mirror
#   routing; ship-mirror-v56 bundles it; latency-bundle-v56, tradeoff-bundle-v56, mirror-cost-v56
#   time it and docs-v56 draws the README's gallery and plot.
# The chair's ceiling (OUT57 [out/v57]): fit-chair-v57 fits the sphere directly to the first FIT57_SHAPES [8] training
#   chairs at each "RESOLUTION LEVEL" of FIT57_CONFIGS: is the direct fit's chair (0.36 voxel IoU, legs
#   webbed into a skirt) held back by the 64 x 64 silhouettes or by the 642-vertex sphere? fit-test-v57 fits the test
#   benches, chairs and tables (DATA36A's) as the app's models are scored on them, and ceiling-v57 sets each fit beside
#   the thirty-sixth bundle's meshes of the same shape's drawings (eval-mirror06-clean-v56): its table and sheet.
#   overfit-chairs-v57: the guide's overfit check on fit-chair-v57's chairs alone: can the predictor learn their legs?
#   overfit-chair1-v57: the same on one of them alone; overfit-chair2-v57 on two, with as many samples of each.
# The faster step and the legged specialist's eleventh round (OUT58 [out/v58], RUNS58 [runs/v58]): speed-v58 times the
#   specialists' training step (bench train) at commit BEFORE58 [5370e93] and now, alternating. bundle36-v58 takes the
#   thirty-sixth bundle from git; data-v58 renders 1,200 fresh bench, chair and table shapes a category (DATA58);
#   import-legs-v58 makes the bundled legged specialist a run again; predictor-v58-legs11 trains it on; check-legs-v58
#   scores it on the choice set (legs11-v58 runs these in order); legs11-route-v58 routes it in the bundle and scores
#   every test sketch beside the bundle's own evals (eval-mirror06-*-v56); versus-v58, ship-compact18-v58.
# The legged specialist on a lent GPU at batch 128 (OUT59 [out/v59], RUNS59 [runs/v59]; the call is in
#   training/gpu_predictor.sh's header): whl-gpu fetches the wheels it carries; fetch-gpu-v59 (GPU_FILES) makes what came
#   back a run (RUNS59/legs12); check-legs-v59 scores it on the choice set beside the bundled specialist;
#   gpulegs12-route-v59 routes it in the bundle and scores every test sketch; versus-v59, ship-compact19-v59.
#   latency-bundle-v59 times the shipped bundle here; supports-v59 counts where the legs are lost (bench supports).
#   Nothing shipped: predictor-v59-legs-n5e4 check-legs-n5e4-v59 supports-choice-v59 (the normal term at a quarter);
#   predictor-v59-legs-band check-legs-band-v59 and predictor-v59-legs-band1 check-legs-band1-v59 (the silhouette's
#   lowest quarter of rows weighing 4 and 2, --support-band-weight); gallery-band-v59 draws their meshes.
# The first models and the experiments that chose today's training defaults (the README's history):
#   data normals normals16 mesh silhouette paper-normal joint export eval eval-strong eval-gt tradeoff
#   gallery docs clamp-trial overfit variants (all-v1 runs the first models' steps in order).
#   Every training step resumes from its last checkpoint when rerun, so a step
#   that was stopped (or a session that ended) continues where it was.
#
# Environment (defaults in brackets):
#   DATA [data/proc30]    dataset folder         RUNS [runs]         training runs
#   OUT  [out/release]    exported variants, eval tables and plots
#   THREADS [1]           torch threads per training process (two trainings side by side on 2 cores)
#   GEN_ITERS [2000] MESH_ITERS [4000] JOINT_ITERS [500]   iterations (the bundled models' values;
#                         both generator widths train GEN_ITERS)
#   SAMPLES [312]         test sketches evaluated (24 per category, evenly spaced; 0 = all 960)
#   TRADEOFF_SAMPLES [156]  test sketches per variant in the error-against-run-time table
#   LOCAL_BOUND [tanh]    the predictor's offset bound (clamp: see the clamp-trial step)
#   DATA2 [data/proc100e4] RUNS2 [runs/v2] OUT2 [out/v2] GEN2_ITERS [3000] MESH2_ITERS [6500]
#   JOINT2_ITERS [150] SAMPLES2 [156]  the bundled models' (issue 16): what one 3-hour session on
#                         2 cores holds, data and evaluation included; more iterations are better
#                         (every step resumes)
set -euo pipefail

DATA=${DATA:-data/proc30}
RUNS=${RUNS:-runs}
OUT=${OUT:-out/release}
THREADS=${THREADS:-1}
GEN_ITERS=${GEN_ITERS:-2000}
MESH_ITERS=${MESH_ITERS:-4000}
JOINT_ITERS=${JOINT_ITERS:-500}
SAMPLES=${SAMPLES:-312}
TRADEOFF_SAMPLES=${TRADEOFF_SAMPLES:-156}
LOCAL_BOUND=${LOCAL_BOUND:-tanh}
# The next models (issue 16): the varied shape library, 100 shapes per category, four elevations,
# today's training defaults (resize generator, compact predictor with the cosine decay).
DATA2=${DATA2:-data/proc100e4}
RUNS2=${RUNS2:-runs/v2}
GEN2_ITERS=${GEN2_ITERS:-3000}
MESH2_ITERS=${MESH2_ITERS:-6500}
JOINT2_ITERS=${JOINT2_ITERS:-150}
SAMPLES2=${SAMPLES2:-156}
OUT2=${OUT2:-out/v2}
OUT4=${OUT4:-out/v4}
OUT5=${OUT5:-out/v5}
OUT6=${OUT6:-out/v6}
OUT7=${OUT7:-out/v7}
RUNS8=${RUNS8:-runs/v8}
OUT8=${OUT8:-out/v8}
RUNS9=${RUNS9:-runs/v9}
OUT9=${OUT9:-out/v9}
RUNS10=${RUNS10:-runs/v10}
OUT10=${OUT10:-out/v10}
RUNS11=${RUNS11:-runs/v11}
OUT11=${OUT11:-out/v11}
RUNS12=${RUNS12:-runs/v12}
OUT12=${OUT12:-out/v12}
RUNS13=${RUNS13:-runs/v13}
OUT13=${OUT13:-out/v13}
RUNS14=${RUNS14:-runs/v14}
OUT14=${OUT14:-out/v14}
OUT15=${OUT15:-out/v15}
RUNS16=${RUNS16:-runs/v16}
OUT16=${OUT16:-out/v16}
OUT17=${OUT17:-out/v17}
RUNS18=${RUNS18:-runs/v18}
OUT18=${OUT18:-out/v18}
RUNS19=${RUNS19:-runs/v19}
OUT19=${OUT19:-out/v19}
RUNS20=${RUNS20:-runs/v20}
OUT20=${OUT20:-out/v20}
DATA20=${DATA20:-data/proc200e4}
OUT21=${OUT21:-out/v21}
RUNS22=${RUNS22:-runs/v22}
OUT22=${OUT22:-out/v22}
DATAV22=${DATAV22:-data/views22}
DATA30=${DATA30:-data/proc300e4}
DATA60=${DATA60:-data/proc600v4}
DATA40=${DATA40:-data/proc400e4}
RUNS23=${RUNS23:-runs/v23}
OUT23=${OUT23:-out/v23}
RUNS24=${RUNS24:-runs/v24}
OUT24=${OUT24:-out/v24}
RUNS25=${RUNS25:-runs/v25}
OUT25=${OUT25:-out/v25}
OUT26=${OUT26:-out/v26}
OUT27=${OUT27:-out/v27}
RUNS27=${RUNS27:-runs/v27}
DATA70=${DATA70:-data/fresh600v4}
DATA72=${DATA72:-data/check1200v4}
RUNS28=${RUNS28:-runs/v28}
OUT28=${OUT28:-out/v28}
OUT29=${OUT29:-out/v29}
RUNS30=${RUNS30:-runs/v30}
OUT30=${OUT30:-out/v30}
OUT31=${OUT31:-out/v31}
OUT32=${OUT32:-out/v32}
OUT33=${OUT33:-out/v33}
OUT34=${OUT34:-out/v34}
OUT35=${OUT35:-out/v35}
DATA100=${DATA100:-data/proc100}
RUNS36=${RUNS36:-runs/v36}
OUT36=${OUT36:-out/v36}
DATA36=${DATA36:-data/legs600v4}
DATA36C=${DATA36C:-data/legs1200v4}
DATA36T=${DATA36T:-data/legs100e4}
DATA36L=${DATA36L:-data/lib1200v4}
DATA36A=${DATA36A:-data/test100e4}
LEGS=(bench chair table)
RUNS37=${RUNS37:-runs/v37}
OUT37=${OUT37:-out/v37}
DATA37=${DATA37:-data/route1300v4}
RUNS38=${RUNS38:-runs/v38}
OUT38=${OUT38:-out/v38}
DATA38N=${DATA38N:-data/legs1250v4}
DATA38=${DATA38:-data/legs2100v4}
RUNS39=${RUNS39:-runs/v39}
OUT39=${OUT39:-out/v39}
DATA39N=${DATA39N:-data/legs1550v4}
DATA39=${DATA39:-data/legs2900v4}
RUNS40=${RUNS40:-runs/v40}
OUT40=${OUT40:-out/v40}
DATA40N=${DATA40N:-data/legs1850v4}
DATA40S=${DATA40S:-data/legs3600v4}
RUNS41=${RUNS41:-runs/v41}
DATA41=${DATA41:-data/second1550v4}
DATA41C=${DATA41C:-data/second1200v4}
OUT41=${OUT41:-out/v41}
RUNS42=${RUNS42:-runs/v42}
RUNS43=${RUNS43:-runs/v43}
RUNS44=${RUNS44:-runs/v44}
OUT44=${OUT44:-out/v44}
DATA44=${DATA44:-data/third1550v4}
DATA44C=${DATA44C:-data/third1200v4}
RUNS45=${RUNS45:-runs/v45}
OUT45=${OUT45:-out/v45}
DATA45N=${DATA45N:-data/third2150v4}
DATA45=${DATA45:-data/third2900v4}
RUNS46=${RUNS46:-runs/v46}
OUT46=${OUT46:-out/v46}
DATA46N=${DATA46N:-data/third2750v4}
DATA46=${DATA46:-data/third4350v4}
RUNS47=${RUNS47:-runs/v47}
OUT47=${OUT47:-out/v47}
OUT43=${OUT43:-out/v43}
DATA43N=${DATA43N:-data/second2750v4}
DATA43=${DATA43:-data/second4350v4}
BUNDLE43=${BUNDLE43:-$OUT43/models_compact7}  # the folder latency-, tradeoff- and docs-v43 measure: the bundle chosen
OUT42=${OUT42:-out/v42}
DATA42N=${DATA42N:-data/second2150v4}
DATA42=${DATA42:-data/second2900v4}  # 2,896 shapes (run predictor-v42-second2 read it as data/second2750v4)
THIRD=(rifle watercraft sofa)  # the three lowest-scoring categories after the specialists' six (eval-compact7-clean-v43)
SECOND=(airplane display lamp)  # the three lowest-scoring categories after the legged three (eval-compact-clean-v40)
# route_counts' ROUTE_GROUPS for a folder routing to the legged and second specialists, and to the third one too
ROUTES2="mesh_predictor_legged.onnx=$(IFS=,; echo "${LEGS[*]}") mesh_predictor_second.onnx=$(IFS=,; echo "${SECOND[*]}")"
ROUTES3="$ROUTES2 mesh_predictor_third.onnx=$(IFS=,; echo "${THIRD[*]}")"
BUNDLE44=${BUNDLE44:-$OUT44/models_compact8}  # the folder latency-, tradeoff- and docs-v44 measure
BUNDLE45=${BUNDLE45:-$OUT45/models_compact9}  # the folder latency-, tradeoff- and docs-v45 measure
BUNDLE47=${BUNDLE47:-$OUT47/models_compact10}  # the folder latency-, tradeoff- and docs-v47 measure
RUNS48=${RUNS48:-runs/v48}
OUT48=${OUT48:-out/v48}
DATA48N=${DATA48N:-data/third3350v4}
DATA48=${DATA48:-data/third5800v4}
BUNDLE48=${BUNDLE48:-$OUT48/models_fast}  # the folder latency-, tradeoff- and docs-v48 measure
OUT49=${OUT49:-out/v49}
RUNS49=${RUNS49:-runs/v49}
DATA49N=${DATA49N:-data/third3950v4}
DATA49=${DATA49:-data/third7250v4}
BUNDLE49=${BUNDLE49:-assets/models}  # the folder latency-app-v49 times
OUT50=${OUT50:-out/v50}
BUNDLE50=${BUNDLE50:-assets/models}  # the folder tradeoff- and docs-v50 measure
RUNS50=${RUNS50:-runs/v50}
DATA50N=${DATA50N:-data/third4550v4}
DATA50=${DATA50:-data/third8700v4}
OUT51=${OUT51:-out/v51}
BUNDLE51=${BUNDLE51:-assets/models}  # the folder latency-, tradeoff- and docs-v51 measure
RUNS51=${RUNS51:-runs/v51}
DATA51=${DATA51:-data/legs2150v4}  # the legged specialist's seventh round: bench, chair and table shapes 2150-2749
OUT52=${OUT52:-out/v52}
BUNDLE52=${BUNDLE52:-assets/models}  # the folder latency-, tradeoff- and docs-v52 measure
RUNS52=${RUNS52:-runs/v52}
DATA52N=${DATA52N:-data/legs2750v4}  # the legged specialist's eighth round: bench, chair and table shapes 2750-3349 ...
DATA52=${DATA52:-data/legs3350v4}  # ... merged with DATA51
OUT53=${OUT53:-out/v53}
BUNDLE53=${BUNDLE53:-assets/models}  # the folder latency-, tradeoff- and docs-v53 measure
RUNS53=${RUNS53:-runs/v53}
DATA53N=${DATA53N:-data/legs3350newv4}  # the legged specialist's ninth round: bench, chair and table shapes 3350-3949 ...
DATA53=${DATA53:-data/legs3950v4}  # ... merged with DATA52
DATACAL=${DATACAL:-data/calib100v4}  # calibration drawings of the int8 generator: 8 shapes a category from 9000 on, train
OUT54=${OUT54:-out/v54}
BUNDLE54=${BUNDLE54:-assets/models}  # the folder latency-, tradeoff- and docs-v54 measure
RUNS54=${RUNS54:-runs/v54}
OUT55=${OUT55:-out/v55}
RUNS55=${RUNS55:-runs/v55}
BUNDLE55=${BUNDLE55:-out/v55/models_bundle34}  # the thirty-fourth bundle (bundle34-v55), whose routing the v55 steps measure
OUT56=${OUT56:-out/v56}
BUNDLE56=${BUNDLE56:-out/v56/models_bundle35}  # the thirty-fifth bundle (bundle35-v56), which the v56 steps route both ways
OUT57=${OUT57:-out/v57}
OUT58=${OUT58:-out/v58}
RUNS58=${RUNS58:-runs/v58}
OUT59=${OUT59:-out/v59}
RUNS59=${RUNS59:-runs/v59}
DATA58N=${DATA58N:-data/legs5150newv4}  # the legged specialist's eleventh round: bench, chair and table shapes 4550-5149,
DATA58M=${DATA58M:-data/legs5750newv4}  # ... shapes 5150-5749 ...
DATA58=${DATA58:-data/legs4550to5749v4}  # ... merged
DATA54N=${DATA54N:-data/legs3950newv4}  # the legged specialist's tenth round: bench, chair and table shapes 3950-4549 ...
DATA54=${DATA54:-data/legs4550v4}  # ... merged with DATA53
COMPACT40=${COMPACT40:-$OUT40/models_routed5}  # the model folder compact-v40 stores in int8 ...
COMPACT40_EVAL=${COMPACT40_EVAL:-$OUT40/route5}  # ... and the prefix of its eval-route folders (<prefix>_clean, ...)
BIG_ARCH="--predictor-channels 64 --predictor-hidden 1024"  # the larger predictor's size (gpu_predictor.sh's ARCH)
# Voxel IoU: a cell is solid when its centre is inside the shape or its surface passes through the cell
# (training.evaluation.metrics.solid_voxels). Every step written before that measure existed scores with cell
# centres only, as its published figures were measured: CENTRES [--voxel-centres]; CENTRES= reruns them with the
# surface's cells. The steps from eval-v6 on use the surface measure.
read -r -a CENTRES <<< "${CENTRES---voxel-centres}"
SHIP_MODELS=${SHIP_MODELS:-$OUT2/models_silhouette_int8}  # the pair ship-v2 bundles (gallery-v2, refine-v2, docs-v2 too)
SHIP_OUT=${SHIP_OUT:-$OUT2}  # where gallery-v2 and refine-v2 write and docs-v2 reads (with OUT2's tradeoff, eval_clean)  # the fourth models (all-v4): the third models' runs (RUNS2=runs/gpu) with the predictor continued
# The normal term's edge gradient, pinned: `train mesh` (and the benches that train) keep the normal image's Eq. 1 edge
# gradient off the outline by default since 2026-11-28 (normal_edges false; model card, "The normal term off the
# outline from the start"); every step written before ran with it on unless it says --no-normal-edges, and passes
# --normal-edges (--set normal_edges=true to the benches) so that it reproduces what it published.
# The first bundled predictor's settings, pinned: the training defaults have since moved on (compact predictor,
# lr 2e-3 with warm-up, K = 3; see the overfit and variants steps), and these steps reproduce what was bundled first.
PREDICTOR=(--predictor-arch softras --predictor-channels 32 --predictor-hidden 512 --predictor-latent 256
           --predictor-local-bound "$LOCAL_BOUND" --lr-mesh 1e-4 --lr-warmup 0 --extra-views 1)
# The first bundled generator's architecture, pinned likewise: new trainings default to "resize" (reflect padding,
# resize-convolutions), the first bundled generator was the original pix2pix U-Net (zero padding, transposed convolutions).
GENERATOR=(--generator-arch pix2pix)

overfit13() {  # overfit-v31's check again into folder $1, then bench overfit's flags: the same 13 shapes (its data,
  # built by running overfit-v31 first when missing), their cached direct fits at damping 4 and, as overfit-v31 ran,
  # the paper's edge gradient on the normal image (a later --set normal_edges=false wins)
  [ -f "$OUT31/overfit/data/manifest.json" ] || step overfit-v31
  local out=$1; shift
  sketchmesh bench overfit --set normal_edges=true --out "$out" --data "$OUT31/overfit/data" --shapes 13 --fit-smoothing 4 "$@"
}
drawings_eval() {  # $1 a dataset, $2 yes|no retrieval, $3 a bench-variants folder, $4 a model-folder prefix, $5 the
  # eval folder, $6 the step that trains the runs when missing, then variant names: each $3/runs/VARIANT exported to
  # $4_VARIANT beside the bundled generator and scored from $1's test drawings (4 a shape) through the app's engine,
  # mirror averaged, the first variant first (the table's paired differences are to it)
  local data=$1 retrieval=$2 runs=$3 prefix=$4 out=$5 prereq=$6 v models=() extra=(--no-retrieval); shift 6
  [ "$retrieval" = yes ] && extra=()
  for v in "$@"; do
    [ -f "$runs/runs/$v/config.json" ] || step "$prereq"
    rm -rf "${prefix}_$v"
    sketchmesh export "$runs/runs/$v" -o "${prefix}_$v"
    cp assets/models/generator.onnx "${prefix}_$v/"
    models+=(--models "${prefix}_$v")
  done
  sketchmesh eval "${models[@]}" --data "$data" --split test --views 4 --mirror-average --threads 2 "${extra[@]}" \
    --out "$out"
}
round_check() {  # a specialist run $2 exported as the app loads the specialists (float16 weights, beside the
  # twenty-first's generator) into $1/models_$3, then the model folders $6... and it (the new one last) scored on the
  # choice set $4 through the app's engine, mirror averaged, into $1/$5; then its paired gains and the category means
  local out=$1 run=$2 name=$3 choice=$4 check=$5 models=() m; shift 5
  rm -rf "$out/models_$name"
  sketchmesh export "$run" -o "$out/models_$name" --quantize fp16
  cp "$OUT36/models_twentyfirst/generator.onnx" "$out/models_$name/"
  for m in "$@" "$out/models_$name"; do models+=(--models "$m"); done
  sketchmesh eval "${models[@]}" --mirror-only --data "$choice" --split train --views 4 --no-retrieval --threads 2 \
    --out "$out/$check"
  choice_versus "$out/$check/eval_models_train.json"
}

legs_check() {  # round_check of the legged specialist's run $2 as $1/models_$3 beside the model folders $4... on its
  # choice set (DATA36C, 129 unseen legged shapes x 4 views), into $1/check_legs
  round_check "$1" "$2" "$3" "$DATA36C" check_legs "${@:4}"
}

choice_versus() {  # an eval JSON of several model columns on the same meshes: the last column minus each earlier one,
  # paired over the meshes (mean +- standard error), the floors left out; then each column's mean per category
  python3 - "$1" <<'PY'
import json, sys
import numpy as np
res = json.load(open(sys.argv[1]))
cols = [c for c in res["columns"] if c not in ("template", "retrieval")]
new = cols[-1]
for c in cols[:-1]:
    d = np.array([r["iou"][new] - r["iou"][c] for r in res["rows"]
                  if r["iou"].get(new) is not None and r["iou"].get(c) is not None])  # a mesh with no view left out
    print(f"{new} minus {c}: {d.mean():+.4f} +- {d.std(ddof=1) / np.sqrt(len(d)):.4f} (paired, {len(d)} meshes)")
for cat in sorted({r["category"] for r in res["rows"]}):  # each column's mean over the category's meshes
    print(f"  {cat}: " + ", ".join(f"{c} {np.mean([r['iou'][c] for r in res['rows'] if r['category'] == cat and r['iou'].get(c) is not None]):.3f}"
                                   for c in cols))
PY
}

route_counts() {  # an eval JSON of one routed folder (mirror only): how often its router sent a drawing of a route's
  # categories and another one to that route, which others, the route's categories' missed drawings and how many of
  # them it named right, and how often it named the drawing's category. The routes:
  # ROUTE_GROUPS ["FILE=CAT,CAT... ..."; the legged specialist alone when unset]
  python3 - "$1" ${ROUTE_GROUPS:-"mesh_predictor_legged.onnx=$(IFS=,; echo "${LEGS[*]}")"} <<'PY'
import json, sys
from collections import Counter
res = json.load(open(sys.argv[1])); col = res["columns"][0]
groups = {g.split("=")[0]: set(g.split("=")[1].split(",")) for g in sys.argv[2:]}
sent = [(r["category"], v["routes"][col]) for r in res["rows"] for v in r["per_view"]]
print(f"{col}: {len(sent)} drawings, category right {sum(c == x['category'] for c, x in sent) / len(sent):.3f}")
for name, cats in groups.items():
    mine = [x for c, x in sent if c in cats]
    others = Counter(c for c, x in sent if c not in cats and x["route"] == name)
    print(f"  to {name}: {sum(x['route'] == name for x in mine)} of {len(mine)} of {', '.join(sorted(cats))}, "
          f"{sum(others.values())} of {len(sent) - len(mine)} others "
          f"({', '.join(f'{c} {k}' for c, k in sorted(others.items())) or 'none'})")
    missed = [(c, x["category"]) for c, x in sent if c in cats and x["route"] != name]
    print(f"    missed: {', '.join(f'{c} {k}' for c, k in sorted(Counter(c for c, _ in missed).items())) or 'none'}; "
          f"of them named right {sum(c == n for c, n in missed)} "
          f"({', '.join(f'{c} {k}' for c, k in sorted(Counter(c for c, n in missed if c == n).items())) or 'none'})")
PY
}

route_eval() {  # a routed folder $2 on every test sketch of case $1 (clean, side or strong: DATA36A's test split at all 48
  # views, canvas path, mirror averaged, no refinement) into $3; then versus_json of the earlier results $4... and it
  local c=$1 folder=$2 out=$3; shift 3
  local extra=(); [ "$c" = side ] && extra=(--elevation 0); [ "$c" = strong ] && extra=(--augment-strength 1.0)
  sketchmesh eval --models "$folder" --mirror-only --data "$DATA36A" --split test --views 0 \
    --sketch-path canvas --no-retrieval "${extra[@]}" --threads 2 --quiet --out "$out" > /dev/null
  versus_json "$@" "$out/eval_models_test.json"
}

legs_data() {  # bench, chair and table shapes $1 onwards (300 a category, train split, 4 grid views each) into $2, merged
  # with $4 into $3, and the fifth generator's images of $3's drawings and of their flipped drawings ($5 "reuse": $4's
  # rows copied with --reuse); resumes. CATS (the categories) and PER_CAT (shapes a category) change the first two
  local cats=("${LEGS[@]}"); [ -n "${CATS:-}" ] && read -r -a cats <<< "$CATS"
  local reuse=(); [ "${5:-}" = reuse ] && reuse=(--reuse "$4")
  sketchmesh data --source procedural --first-shape "$1" --shapes-per-category "${PER_CAT:-300}" --categories "${cats[@]}" \
    --views 12 --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$2"
  sketchmesh data merge "$3" "$4" "$2"
  sketchmesh data generated "$3" --models "$OUT8/models_fifth" --name normals16 --workers 2 "${reuse[@]}"
  sketchmesh data generated "$3" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2 "${reuse[@]}"
}

legs_round() {  # the predictor run $1 trained on by the specialists' CPU recipe (recipe20 at V36_LR [2e-4]) along a new
  # cosine on the data folder $2 into $3; V36_ITERS [3000], V36_MINUTES [65] at most; resumes
  RECIPE_LR=${V36_LR:-2e-4} DATA20=$2 recipe20 "$1" "$3" "${V36_ITERS:-3000}" "${V36_MINUTES:-65}" 2
}

specialist_round() {  # step $1 (data-vN, predictor-vN-NAME, check-KIND-vN, or NAME-vN: the three in order) of a
  # specialist's round that trains the last round's run on along a new cosine: $2 the specialist (second: airplane, display and lamp, choice set DATA41C; third:
  # rifle, watercraft and sofa, DATA44C; legs: bench, chair and table, DATA36C), $3 the round's number (52) and $4 its
  # name (legs8), $5 the last round's number and $6 its name, $7 the number of the data it adds to (DATA$7, made by
  # data-v$7), $8 the first of the new shapes (600 a category, train split, 4 grid views each: DATA$3N, merged with DATA$7
  # into DATA$3; no stage has seen them); the model folders after the twenty-first that the check scores it beside,
  # $9... [the last round's]. The folders DATAn, RUNSn and OUTn by the rounds' numbers; the data and training resume
  local kind=$2 n=$3 name=$4 p=$5 pname=$6 d=$7 first=$8 v cats choice
  v=DATA${n}N; local datan=${!v}; v=DATA$n; local data=${!v}; v=DATA$d; local pdata=${!v}
  v=RUNS$n; local runs=${!v}; v=RUNS$p; local pruns=${!v}; v=OUT$n; local out=${!v}; v=OUT$p; local pout=${!v}
  local earlier=("${@:9}"); [ ${#earlier[@]} -gt 0 ] || earlier=("$pout/models_$pname")
  case $kind in
    second) cats=("${SECOND[@]}"); choice=$DATA41C ;;
    third) cats=("${THIRD[@]}"); choice=$DATA44C ;;
    legs) cats=("${LEGS[@]}"); choice=$DATA36C ;;
    *) echo "specialist_round: no specialist $kind" >&2; return 2 ;;
  esac
  case $1 in
    data-v"$n")
      [ -f "$pdata/.cache/generated/normals16_mirror/info.json" ] || step "data-v$d"
      CATS="${cats[*]}" PER_CAT=600 legs_data "$first" "$datan" "$data" "$pdata" reuse ;;
    predictor-v"$n-$name")  # V36_ITERS [3000], V36_MINUTES [65] at most
      [ -f "$pruns/$pname/config.json" ] || step "predictor-v$p-$pname"
      [ -f "$data/.cache/generated/normals16_mirror/info.json" ] || step "data-v$n"
      legs_round "$pruns/$pname" "$data" "$runs/$name" ;;
    check-"$kind"-v"$n")  # exported as the specialists are (OUTn/models_NAME: float16 weights, beside the twenty-first's
      # generator) and scored on the choice set (rendered first where missing) into OUTn/check_KIND; its paired gains
      [ -f "$runs/$name/config.json" ] || step "predictor-v$n-$name"
      [ -f "$pout/models_$pname/mesh_predictor.onnx" ] || step "check-$kind-v$p"
      choice_data "$choice" "${cats[@]}"
      if [ "$kind" = legs ]; then
        legs_check "$out" "$runs/$name" "$name" "$OUT36/models_twentyfirst" "${earlier[@]}"
      else
        round_check "$out" "$runs/$name" "$name" "$choice" "check_$kind" "$OUT36/models_twentyfirst" "${earlier[@]}"
      fi ;;
    "$name-v$n")  # the three in order (about 2 hours on 2 cores)
      for s2 in "data-v$n" "predictor-v$n-$name" "check-$kind-v$n"; do step "$s2"; done ;;
    *) echo "specialist_round: no step $1 in round $n ($name)" >&2; return 2 ;;
  esac
}

legs_supports() {  # how the meshes stand: the twenty-first pair and the model folder $1, mirror averaged, on DATA36T's legged
  # test shapes at 12 views each (canvas path), retrieval among DATA36L's unseen shapes as the real shapes; into $2
  sketchmesh eval --models "$OUT36/models_twentyfirst" --models "$1" --mirror-only --data "$DATA36T" --split test \
    --views 12 --sketch-path canvas --retrieval-data "$DATA36L" --threads 2 --out "$2"
}

compact_folder() {  # the model folder $1 with every network's large Conv / Gemm weights stored in int8, one float32 scale
  # per output channel, computed in float32 (engine.bench.compact_model, the `int8w` precision of the benches; a router's
  # specialists too), into $2 (replaced); each file's size before and after, and what loading costs
  rm -rf "$2" "$2_work"
  python3 - "$1" "$2" <<'PY'
import shutil, sys
from pathlib import Path
from engine.bench import make_variant
src, dst = Path(sys.argv[1]), Path(sys.argv[2])
work = dst.with_name(dst.name + "_work")
made = make_variant(src, "int8w", work)
shutil.move(str(made), str(dst))
(dst / ".complete").unlink()
shutil.rmtree(work)
for f in sorted(dst.glob("*.onnx")):
    print(f"{f.name}: {(src / f.name).stat().st_size:,} -> {f.stat().st_size:,} bytes")
print(f"in all: {sum((src / f.name).stat().st_size for f in dst.glob('*.onnx')):,} -> "
      f"{sum(f.stat().st_size for f in dst.glob('*.onnx')):,} bytes")
import time
import numpy as np
from engine.models import load_generator, load_predictor
for name, load in (("generator.onnx", load_generator), ("mesh_predictor.onnx", load_predictor)):
    ms = {}
    for folder in (src, dst):  # what loading costs once (the folds happen here), p50 of 5, 2 threads
        t = []
        for _ in range(5):
            t0 = time.perf_counter(); load(folder / name, 2); t.append((time.perf_counter() - t0) * 1e3)
        ms[folder.name] = float(np.median(t))
    print(f"{name} load p50: " + ", ".join(f"{k} {v:.0f} ms" for k, v in ms.items()))
PY
}

fresh_data() {  # shapes 1550-2149 of the categories $2... (train split, 4 grid views each; shapes no stage has trained on:
  # the router's are 1300-1549, the choice and retrieval library's 1200-1249) into $1, and the fifth generator's images of
  # the drawings and of their flipped drawings; resumes
  local out=$1; shift
  [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
  sketchmesh data --source procedural --first-shape 1550 --shapes-per-category 600 --categories "$@" \
    --views 12 --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$out"
  sketchmesh data generated "$out" --models "$OUT8/models_fifth" --name normals16 --workers 2
  sketchmesh data generated "$out" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2
}

first_check() {  # a specialist's first round, the run $1, on its choice set $2 (shapes 1200-1249 of the categories $5...,
  # train split, 4 grid views each; rendered, or completed, first): round_check beside the twenty-first as $3/models_$4,
  # into $3/check_$4
  local run=$1 choice=$2 out=$3 name=$4; shift 4
  choice_data "$choice" "$@"
  round_check "$out" "$run" "$name" "$choice" "check_$name" "$OUT36/models_twentyfirst"
}

choice_data() {  # a specialist's choice set $1: shapes 1200-1249 of the categories $2... (train split, 4 grid views each);
  # resumes (a complete folder is left as it is)
  local choice=$1; shift
  sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --categories "$@" \
    --views 12 --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$choice"
}

routed_swap() {  # a copy $3 of the routed folder $1 with the specialist of the model folder $2 as $4
  # [mesh_predictor_legged.onnx]
  rm -rf "$3"; mkdir -p "$(dirname "$3")"; cp -r "$1" "$3"
  cp "$2/mesh_predictor.onnx" "$3/${4:-mesh_predictor_legged.onnx}"
}

router_variant() {  # a copy $2 (replaced) of the model folder $1 with its router's metadata changed by `sketchmesh router
  # set` $3..., every network but router.onnx checked byte-equal to BUNDLE56's
  rm -rf "$2"; cp -r "$1" "$2"
  sketchmesh router set "$2" "${@:3}"
  same_except "$2" "$BUNDLE56" router.onnx
}

bundle_eval() {  # routed_eval of the bundle folder $1 (made by step $2 when missing) on every test sketch of case $3 into
  # $4, rendering the test split first where missing (data-test-v47)
  [ -f "$DATA36A/manifest.json" ] || step data-test-v47
  [ -f "$1/router.onnx" ] || step "$2"
  ROUTE_GROUPS=$ROUTES3 routed_eval "$3" "$1" "$4"
}

variant_eval() {  # routed_eval of the v56 folder OUT56/models_$1 (made by step $2 when missing) on every test sketch of
  # case $3 into OUT56/$1_$3, beside the earlier folders' results OUT56/<name>_$3 of the names $4... (eval-<name>-$3-v56
  # first where missing)
  local name=$1 make=$2 c=$3 v prev=(); shift 3
  [ -f "$OUT56/models_$name/router.onnx" ] || step "$make"
  for v in "$@"; do
    [ -f "$OUT56/${v}_$c/eval_models_test.json" ] || step "eval-$v-$c-v56"
    prev+=("$OUT56/${v}_$c/eval_models_test.json")
  done
  ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT56/models_$name" "$OUT56/${name}_$c" "${prev[@]}"
}

routed_eval() {  # route_eval of a folder routing to the specialists ($1 the case, $2 the folder, $3 the eval folder,
  # $4... earlier results), then where its router sent the drawings, route by route (ROUTE_GROUPS [ROUTES2])
  route_eval "$@"
  ROUTE_GROUPS=${ROUTE_GROUPS:-$ROUTES2} route_counts "$3/eval_models_test.json"
}

compact_swap() {  # a copy $3 (replaced) of the model folder $1 with the specialist $2/mesh_predictor.onnx stored as the
  # bundle stores it (compact_model: int8 weights, one scale per output channel) as $4; its other files checked byte-equal
  rm -rf "$3"; cp -r "$1" "$3"
  python3 -c 'import sys; from engine.bench import compact_model; compact_model(sys.argv[1], sys.argv[2])' \
    "$2/mesh_predictor.onnx" "$3/$4"
  ls -l "$2/mesh_predictor.onnx" "$3/$4"
  same_except "$3" "$1" "$4"
}

router_diff() {  # the largest difference of the routed folder $2's router probabilities from $1's on 64 random images and
  # 8 blank ones, and $2's routes and threshold
  python3 - "$1" "$2" <<'PY'
import sys
import numpy as np
from engine.models import load_router
old, new = (load_router(f"{d}/router.onnx", 2) for d in sys.argv[1:])
x = np.random.default_rng(0).random((72, 3, 64, 64), dtype=np.float32); x[64:] = 0.0
p = [r.session.run(None, {r.input_name: x})[0] for r in (old, new)]
print(f"router probabilities, new minus bundled: max |difference| {np.abs(p[1] - p[0]).max():.2e}; routes {new.routes}, "
      f"threshold {new.route_threshold}")
PY
}

case_routes() {  # route_counts (ROUTE_GROUPS $1) of each case's eval of one routed folder: $2_<case>/eval_models_test.json
  local c
  for c in clean side strong; do
    echo "$c:"
    ROUTE_GROUPS=$1 route_counts "$2_$c/eval_models_test.json"
  done
}

specialist_route() {  # step $1 of the specialist $2's (second, third or legs) round $3 (53) named $4 (legs9: its model
  # folder OUT$3/models_$4, made by check-$2-v$3, whose choice-set eval is OUT$3/check_$2) routed and measured as the
  # bundle runs it: the folder OUT$3/models_$5 is the bundle OUT$6/models_$7 (made by step $7-v$6) with that specialist
  # stored as the bundle stores it (mesh_predictor_$2.onnx; _legged for legs). Its steps, with tag = v$3: $5-tag (that
  # folder); eval-$5-<case>-tag (every test sketch of the case beside OUT$6/$7_<case>'s eval: both means, the paired
  # difference, the three routes); gallery-$5-tag; <round>-route-tag (these in order, clean first: about 30 min on 2
  # cores); versus-tag (the choice set paired and per category, and each case's routes, from the JSONs written);
  # ship-$5-tag (the specialist into assets/models, the other files checked byte-equal)
  local what=$1 kind=$2 n=$3 round=$4 name=$5 p=$6 prev=$7 v c
  v=OUT$n; local out=${!v}; v=OUT$p; local pout=${!v}
  local tag=v$n ptag=v$p spec=$out/models_$round check=check-$kind-v$n check_dir=$out/check_$kind file
  if [ "$kind" = legs ]; then file=mesh_predictor_legged.onnx; else file=mesh_predictor_$kind.onnx; fi
  case $what in
    "$name-$tag")
      [ -f "$spec/mesh_predictor.onnx" ] || step "$check"
      [ -f "$pout/models_$prev/router.onnx" ] || step "$prev-$ptag"
      compact_swap "$pout/models_$prev" "$spec" "$out/models_$name" "$file" ;;
    eval-"$name"-*-"$tag")
      c=${what#eval-"$name"-}; c=${c%-"$tag"}
      [ -f "$out/models_$name/router.onnx" ] || step "$name-$tag"
      [ -f "$pout/${prev}_$c/eval_models_test.json" ] || step "eval-$prev-$c-$ptag"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$out/models_$name" "$out/${name}_$c" "$pout/${prev}_$c/eval_models_test.json" ;;
    gallery-"$name"-"$tag")
      [ -f "$out/models_$name/router.onnx" ] || step "$name-$tag"
      route_gallery "$out/models_$name" "$out/gallery_$name" ;;
    *-route-"$tag")
      for c in "$name-$tag" "eval-$name-clean-$tag" "eval-$name-side-$tag" "eval-$name-strong-$tag" "gallery-$name-$tag"; do
        step "$c"
      done ;;
    versus-"$tag")
      choice_versus "$check_dir/eval_models_train.json"
      case_routes "$ROUTES3" "$out/$name" ;;
    ship-"$name"-"$tag")
      [ -f "$out/models_$name/router.onnx" ] || step "$name-$tag"
      ship_files "$out/models_$name" "$file" ;;
  esac
}

same_except() {  # every network of the model folder $1 but the files $3... checked byte-equal to the folder $2's
  local f
  for f in "$1"/*.onnx; do
    case " ${*:3} " in *" $(basename "$f") "*) ;; *) cmp "$f" "$2/$(basename "$f")" || return 1 ;; esac
  done
}

ship_files() {  # the model folder $1's files $2... copied into assets/models, its other networks first checked byte-equal
  # to the bundle's (same_except)
  same_except "$1" assets/models "${@:2}"
  local f
  for f in "${@:2}"; do cp "$1/$f" assets/models/; done
}

router_export() {  # router-v37's run exported into the routed folder $1 with the routes $2 ("FILE=CAT,CAT... ...", as
  # ROUTES2 / ROUTES3) at ROUTE_THRESHOLD [0.8]
  local routes=() g
  for g in $2; do routes+=(--route "$g"); done
  sketchmesh router export "$RUNS37/router" --models "$1" "${routes[@]}" --threshold "${ROUTE_THRESHOLD:-0.8}"
}

bundle_latency() {  # the app's path timed as latency-compact-v40 for the folder $1 (bench refine, 156 clean and strong test
  # sketches, mirror averaged, outline refinement 0 and 3 steps; run it alone: it times), into $2
  sketchmesh bench refine --data "$DATA36A" --models "$1" --max-samples "$SAMPLES2" --mirror-average \
    --steps 0 3 --no-intersections --threads 2 --quiet --out "$2"
}

bundle_tradeoff() {  # error against run time for the folder $1 as stored (the precision fp32: the files as given) and with
  # dynamic int8 on top, one pass and mirror averaged, on TRADEOFF_SAMPLES clean test sketches, into $2 (run it alone)
  sketchmesh bench tradeoff --data "$DATA36A" --variant "routed=$1" --precisions fp32 int8 fp32+mirror \
    int8+mirror --bundled "routed:fp32+mirror" --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$2"
}

bundle_docs() {  # the README's gallery and error-against-run-time plot, of the folder $1: its gallery (route_gallery) into
  # $2{,_side}.png, copied with the tradeoff plot of $3 into docs/
  route_gallery "$1" "$2"
  cp "$2.png" docs/gallery.png
  cp "$2_side.png" docs/gallery_side.png
  cp "$3/tradeoff.png" docs/tradeoff.png
}

bundle_round() {  # a round's bundle measured: $1 latency, tradeoff or docs, of the folder $2 (made by step $4 first when
  # it is the round's own folder $3 and missing), into the round's output folder $5 (latency_bundle, tradeoff_bundle,
  # gallery_bundle*); $6 the round (v47) whose tradeoff-bundle step docs needs
  [ -f "$2/router.onnx" ] || [ "$2" != "$3" ] || step "$4"
  case $1 in
    latency|tradeoff) [ -f "$DATA36A/manifest.json" ] || step data-test-v47 ;;
    docs) [ -f "$5/tradeoff_bundle/tradeoff.png" ] || step "tradeoff-bundle-$6" ;;
  esac
  case $1 in
    latency) bundle_latency "$2" "$5/latency_bundle" ;;
    tradeoff) bundle_tradeoff "$2" "$5/tradeoff_bundle" ;;
    docs) bundle_docs "$2" "$5/gallery_bundle" "$5/tradeoff_bundle" ;;
  esac
}

route_gallery() {  # the gallery of a model folder $1 (one test shape a category, from 30 degrees and from the side, mirror
  # averaged): $2.png and $2_side.png
  sketchmesh gallery --data "$DATA36A" --models "$1" --mirror-average --threads 2 -o "$2.png"
  sketchmesh gallery --data "$DATA36A" --models "$1" --mirror-average --elevation 0 --azimuth 90 --threads 2 -o "$2_side.png"
}

versus_json() {  # eval JSONs of the same drawings (mirror only), the last one a single column: every column's 13-category
  # mean (+- one standard error, the test shapes as the draws) and the last column's paired difference from each earlier one
  python3 - "$@" <<'PY'
import json, sys
from collections import defaultdict
*olds, new = (json.load(open(f)) for f in sys.argv[1:])
col = new["columns"][0]
cols = [c for old in olds for c in old["columns"] if c not in ("template", "retrieval")] + [col]  # the floors left out
iou = defaultdict(dict)
for res in olds + [new]:
    for r in res["rows"]:
        iou[(r["category"], r["shape_id"])].update(r["iou"])
def mean_se(f):
    per = defaultdict(list)
    for (cat, _), d in iou.items():
        per[cat].append(f(d))
    m = sum(sum(x) / len(x) for x in per.values()) / len(per)
    v = sum(sum((y - sum(x) / len(x)) ** 2 for y in x) / (len(x) - 1) / len(x) for x in per.values() if len(x) > 1)
    return m, v ** 0.5 / len(per), per
for c in cols:
    m, se, per = mean_se(lambda d: d[c])
    print(f"{c}: mean of {len(per)} categories {m:.4f} +- {se:.4f}; "
          + ", ".join(f"{k} {sum(x) / len(x):.3f}" for k, x in sorted(per.items())))
for c in cols[:-1]:
    m, se, _ = mean_se(lambda d: d[col] - d[c])
    print(f"{col} minus {c}: {m:+.4f} +- {se:.4f} (paired, test shapes)")
PY
}

route_summary() {  # $1 an eval JSON of the bundled pair and a routed folder (mirror only): how often the router sent a
  # legged drawing (LEGS) to the specialist and another one, its category accuracy, and both 13-category means with the
  # paired difference (standard error over the test shapes)
  python3 - "$1" "${LEGS[@]}" <<'PY'
import json, sys
from collections import Counter, defaultdict
res = json.load(open(sys.argv[1])); legs = set(sys.argv[2:])
base, routed = res["columns"][0], res["columns"][1]
views = [(r["category"], v) for r in res["rows"] for v in r["per_view"]]
n, sent = len(views), [(cat, v["routes"][routed]) for cat, v in views]
leg = sum(c in legs for c, _ in sent)
print(f"{n} drawings ({leg} legged): category right {sum(c == r['category'] for c, r in sent) / n:.3f}; sent to the "
      f"specialist: {sum(c in legs and r['route'] is not None for c, r in sent)} of {leg} legged, "
      f"{sum(c not in legs and r['route'] is not None for c, r in sent)} of {n - leg} others "
      f"({', '.join(f'{c} {k}' for c, k in sorted(Counter(c for c, r in sent if c not in legs and r['route']).items())) or 'none'})")
per = defaultdict(lambda: defaultdict(list))
for r in res["rows"]:
    for col in (base, routed):
        per[col][r["category"]].append(r["iou"][col])
means = {col: {c: sum(x) / len(x) for c, x in per[col].items()} for col in (base, routed)}
diff = defaultdict(list)
for r in res["rows"]:
    diff[r["category"]].append(r["iou"][routed] - r["iou"][base])
def se(groups):  # standard error of the mean over categories, each category's test shapes as its draws
    v = sum(sum((d - sum(x) / len(x)) ** 2 for d in x) / (len(x) - 1) / len(x) for x in groups.values() if len(x) > 1)
    return v ** 0.5 / len(groups)
for col in (base, routed):
    m = means[col]
    print(f"{col}: mean of {len(m)} categories {sum(m.values()) / len(m):.4f} +- {se(per[col]):.4f}; "
          + ", ".join(f"{c} {v:.3f}" for c, v in sorted(m.items())))
print(f"routed minus bundled: {sum(sum(x) / len(x) for x in diff.values()) / len(diff):+.4f} +- {se(diff):.4f} "
      "(paired, test shapes)")
PY
}

eval_case() {  # EVAL_EXTRA and EVAL_NAME of an eval step: clean sketches, strong augmentation, side views, GT normals
  case "$1" in
    eval-strong-*) EVAL_EXTRA=(--augment-strength 1.0); EVAL_NAME=eval_strong ;;
    eval-side-*) EVAL_EXTRA=(--elevation 0); EVAL_NAME=eval_side ;;
    eval-gt-*) EVAL_EXTRA=(--gt-normals); EVAL_NAME=eval_gt_normals ;;
    *) EVAL_EXTRA=(); EVAL_NAME=eval_clean ;;
  esac
}

export_pair() {  # training run $1 exported as float32 and int8 into $2/models_fp32 and $2/models_int8, beside generator file $3
  for q in fp32 int8; do
    rm -rf "$2/models_$q"
    local quant=(); [ "$q" = int8 ] && quant=(--quantize int8)
    sketchmesh export "$1" -o "$2/models_$q" "${quant[@]}"
    cp "$3" "$2/models_$q/"
  done
}

import_run() {  # the model folder $1's predictor back as a run in $2 (its weights made float32, batch norms calibrated on
  # the generated images of the dataset $3), unless $2 holds one already
  [ -f "$2/predictor/config.json" ] || sketchmesh import-models "$1" --out "$2" --only predictor --data "$3" --threads 2
}

models_from_git() {  # the bundled pair of commit $1 (assets/models) into folder $2
  mkdir -p "$2"
  for f in generator.onnx mesh_predictor.onnx; do git show "$1:assets/models/$f" > "$2/$f"; done
}

bundle_from_git() {  # every network of commit $1's assets/models (a routed bundle: router and specialists too) into folder $2
  rm -rf "$2"; mkdir -p "$2"
  local f
  for f in $(git ls-tree --name-only "$1" assets/models/ | grep '\.onnx$'); do git show "$1:$f" > "$2/$(basename "$f")"; done
}

eval_against() {  # $1 split, $2 out folder, $3 run, then baseline runs: the case of eval_case's EVAL_EXTRA from the
  # fifth generator's images (SAMPLES2 sketches, no retrieval)
  local split=$1 out=$2 run=$3 bases=() b; shift 3
  for b in "$@"; do bases+=(--baseline-run "$b"); done
  sketchmesh eval "$run" --data "$DATA2" --split "$split" --generator-run "$RUNS8/fifth/generator" "${bases[@]}" \
    --no-retrieval "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 --out "$out"
}

tradeoff_of() {  # $1 a name, $2 a folder holding models_fp32: error against run time in the app's engine at each
  # precision and template level, the float32 pair marked as bundled, into $2/tradeoff (run it alone: it times)
  sketchmesh bench tradeoff --data "$DATA2" --variant "$1=$2/models_fp32" --precisions fp32 int8-predictor int8 \
    --levels 2 3 4 --bundled "$1:fp32" --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$2/tradeoff"
}

compare_pairs() {  # $1: an OUT folder; then commits: their bundled pairs (from git) and $1/final/models_fp32 through the
  # app's ONNX path on 39 test shapes x 4 drawings, with retrieval and the template sphere, into $1/final/compare
  local out=$1 folders=() c; shift
  for c in "$@"; do
    models_from_git "$c" "$out/models_$c"
    folders+=(--models "$out/models_$c")
  done
  sketchmesh eval "${folders[@]}" --models "$out/final/models_fp32" --data "$DATA2" --views 4 --max-samples 39 \
    --threads 2 --out "$out/final/compare"
}

train7() {  # the seventh predictor's recipe from run $1 into run $2: $3 iterations (Adam 2e-4 cosine), $4 minutes at most,
  # $5 threads, normal weight $6 [0.002] (its gradient kept off the outline), on the generator's images with half of every
  # batch mirrored from the generator's images of the flipped drawings; resumes (TRAIN_LR: another peak rate;
  # TRAIN_DATA: another dataset than DATA2 with the same generated sets; TRAIN_INPUTS: another generated set than
  # normals16, with its NAME_mirror)
  # shellcheck disable=SC2086  # PRED_ARCH: predictor size flags of a run of another size (BIG_ARCH); TRAIN_EXTRA: more flags
  sketchmesh train mesh --data "${TRAIN_DATA:-$DATA2}" --init-mesh "$1" ${PRED_ARCH:-} ${TRAIN_EXTRA:-} --lambda-n "${6:-0.002}" --lr-mesh "${TRAIN_LR:-2e-4}" --iters "$3" \
    --threads "$5" --ckpt-every 250 --val-every 0 --quiet --max-minutes "$4" --input-normals "${TRAIN_INPUTS:-normals16}" \
    --no-normal-edges --mirror 0.5 --mirror-inputs "${TRAIN_INPUTS:-normals16}_mirror" --out "$2"
}

v27_start() {  # what a training step from the twenty-first on DATA70 needs ($1 the step): the generated sets (or a
  # clear error) and the twenty-first imported as a run (import-v27 when it is not there)
  [ -f "$DATA70/.cache/generated/normals16_mirror/info.json" ] || { echo "$1 reads $DATA70: run data-v27 generated-v27 generated-mirror-v27 first" >&2; exit 1; }
  [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
}

check72() {  # the twenty-first pair (import-v27's run with the fifth generator) against the runs $2... on DATA72 (rendered
  # when absent; its train split), in EVAL_EXTRA's case, CHECK_SAMPLES [520] sketches, into $1
  [ -f "$DATA72/manifest.json" ] || step data-v27-check
  local out=$1 runs=() r; shift
  for r in "$@"; do runs+=(--baseline-run "$r"); done
  sketchmesh eval "$RUNS27/twentyfirst/predictor" --data "$DATA72" --split train --generator-run "$RUNS8/fifth/generator" \
    "${runs[@]}" --no-retrieval "${EVAL_EXTRA[@]}" --max-samples "${CHECK_SAMPLES:-520}" --threads 2 --out "$out"
}

joint28() {  # the end-to-end fine-tune of the twenty-first pair: the fifth generator (import-v8) trained through the
  # twenty-first predictor held fixed (import-v27) on DATA70, into run $1 for $2 iterations at batch 4 on two threads,
  # generator rate $3 (RMSProp), mesh-loss weight $4, then more `train joint` flags (the adversarial term off, so no
  # discriminator runs: the imported generator comes without one); resumes
  v27_start "joint"
  local run=$1 iters=$2 lr=$3 weight=$4; shift 4
  sketchmesh train joint --data "$DATA70" --init-normals "$RUNS8/fifth/generator" --init-mesh "$RUNS27/twentyfirst/predictor" \
    $BIG_ARCH --predictor-aligned 128 --base-channels 16 --generator-arch resize --freeze-predictor --lambda-adv 0 \
    --no-normal-edges --lr-g "$lr" --joint-mesh-weight "$weight" --iters "$iters" --batch 4 --threads 2 --val-every 0 \
    --ckpt-every 250 --log-every 20 --quiet --out "$run" "$@"
}

recipe20() {  # predictor-v19's batch-32 recipe on DATA20 (the larger predictor with the aligned branch, mirror-consistency 50,
  # peak 1e-4 cosine): train7 from run $1 into run $2, $3 iterations, $4 minutes at most, $5 threads (RECIPE_LR: another
  # peak rate; RECIPE_EXTRA: more `train mesh` flags, e.g. --batch)
  PRED_ARCH="$BIG_ARCH --predictor-aligned 128" TRAIN_EXTRA="--mirror-consistency 50 ${RECIPE_EXTRA:-}" \
    TRAIN_LR=${RECIPE_LR:-1e-4} TRAIN_DATA=$DATA20 train7 "$@"
}

more_pass() {  # predictor-vN-more's runs in RUNS20 (N = $1: 20, 21 or 22): MORE_FROM its start, MORE_TO its run
  MORE_TO=v$1_more MORE_FROM=v$(($1 - 1))_more
  [ "$1" = 20 ] && MORE_FROM=v20_data
  return 0
}

pass40() {  # predictor-vN-more's runs on DATA40 in RUNS24 (N = $1: 24 or 25): PASS_FROM its start, PASS_TO its run
  PASS_FROM=v24_data PASS_TO=v24_more
  [ "$1" = 25 ] && PASS_FROM=v24_more PASS_TO=v25_more
  return 0
}

candidate() {  # the shipped candidate of step $1 (its suffix: v15, v17, v18, v19, v20, v21, v22, v23, v24, v25, v26 or v27): CAND_RUN its run, CAND_BASE the run its
  # test figures are measured against, CAND_OUT its folder, CAND_NAME its short name, CAND_PREV the commit whose
  # bundled pair compare-* sets beside it (as CAND_PREV_NAME), CAND_RETRIEVAL the dataset whose train split it saw
  # (where compare-* searches for retrieval; DATA2 unless set)
  case "${1##*-}" in
    v15) CAND_RUN=$RUNS14/v15_control CAND_BASE=$RUNS14/v14_big_mc CAND_OUT=$OUT15 CAND_NAME=v15 CAND_PREV=074b7ab \
         CAND_PREV_NAME=tenth ;;
    v17) CAND_RUN=$RUNS16/v17_aligned CAND_BASE=$RUNS14/v15_control CAND_OUT=$OUT17 CAND_NAME=v17 CAND_PREV=36980ac \
         CAND_PREV_NAME=eleventh ;;
    v18) CAND_RUN=$RUNS18/v18_more CAND_BASE=$RUNS18/twelfth/predictor CAND_OUT=$OUT18 CAND_NAME=v18 \
         CAND_PREV=${TWELFTH:-daf5cee} CAND_PREV_NAME=twelfth ;;
    v19) CAND_RUN=$RUNS19/${V19_RUN:-g19} CAND_BASE=$RUNS18/v18_more CAND_OUT=$OUT19 CAND_NAME=v19 \
         CAND_PREV=${THIRTEENTH:-652c7ea} CAND_PREV_NAME=thirteenth ;;
    v20) CAND_RUN=$RUNS20/${V20_RUN:-v20_data} CAND_BASE=$RUNS19/g19 CAND_OUT=$OUT20 CAND_NAME=v20 \
         CAND_PREV=${FOURTEENTH:-59e0ed8} CAND_PREV_NAME=fourteenth CAND_RETRIEVAL=$DATA20 ;;
    v21) CAND_RUN=$RUNS20/v20_more CAND_BASE=$RUNS20/v20_data CAND_OUT=$OUT21 CAND_NAME=v21 \
         CAND_PREV=${FIFTEENTH:-ca841da} CAND_PREV_NAME=fifteenth CAND_RETRIEVAL=$DATA20 ;;
    v22) CAND_RUN=$RUNS20/v21_more CAND_BASE=$RUNS20/v20_more CAND_OUT=$OUT22 CAND_NAME=v22 \
         CAND_PREV=${SIXTEENTH:-9864ddb} CAND_PREV_NAME=sixteenth CAND_RETRIEVAL=$DATA20 ;;
    v23) CAND_RUN=$RUNS23/v23_data CAND_BASE=$RUNS20/v21_more CAND_OUT=$OUT23 CAND_NAME=v23 \
         CAND_PREV=${SEVENTEENTH:-d45a035} CAND_PREV_NAME=seventeenth CAND_RETRIEVAL=$DATA30 ;;
    v24) CAND_RUN=$RUNS24/v24_data CAND_BASE=$RUNS23/v23_data CAND_OUT=$OUT24 CAND_NAME=v24 \
         CAND_PREV=${EIGHTEENTH:-ba772d1} CAND_PREV_NAME=eighteenth CAND_RETRIEVAL=$DATA40 ;;
    v25) CAND_RUN=$RUNS24/v24_more CAND_BASE=$RUNS24/v24_data CAND_OUT=$OUT25 CAND_NAME=v25 \
         CAND_PREV=${NINETEENTH:-6dc2126} CAND_PREV_NAME=nineteenth CAND_RETRIEVAL=$DATA40 ;;
    v26) CAND_RUN=$RUNS25/${V26_RUN:-g25b} CAND_BASE=$RUNS24/v24_more CAND_OUT=$OUT26 CAND_NAME=v26 \
         CAND_PREV=${TWENTIETH:-af7d5fe} CAND_PREV_NAME=twentieth CAND_RETRIEVAL=$DATA40 ;;
    v27) CAND_RUN=$RUNS27/v27_fresh CAND_BASE=$RUNS27/twentyfirst/predictor CAND_OUT=$OUT27 CAND_NAME=v27 \
         CAND_PREV=${TWENTYFIRST:-2a2eadb} CAND_PREV_NAME=twentyfirst CAND_RETRIEVAL=$DATA40 ;;
    *) echo "reproduce_models.sh: no shipped candidate for step '$1'" >&2; exit 2 ;;
  esac
}

play_session() {  # one scripted app session (sketchmesh --open SAMPLE --report), report $1, in the real window (Xvfb
  # when headless)
  local run=(sketchmesh --open assets/samples/car_car_00002_v3.png --report "$1")
  if [ -n "${DISPLAY:-}" ]; then "${run[@]}"; else xvfb-run -a -s "-screen 0 1600x1000x24" "${run[@]}"; fi
}

blank_session() {  # play_session on a blank canvas (sketchmesh --report: no background layer, so the engine is
  # sent the strokes themselves), report $1
  local run=(sketchmesh --report "$1")
  if [ -n "${DISPLAY:-}" ]; then "${run[@]}"; else xvfb-run -a -s "-screen 0 1600x1000x24" "${run[@]}"; fi
}

play_sessions() {  # three of play_session into folder $1
  mkdir -p "$1"
  local i
  for i in 1 2 3; do play_session "$1/session_$i.json"; done
}

session_table() {  # the session reports in folder $1 named LABEL_k.json: per LABEL, the mean over its runs of the UI
  # lag (p99, max), pen up to mesh on screen (p50), the engine (p50), its preprocess and generator stages (p50), the
  # render thread (p50), and the UI lag's max while erasing (reports since 2026-11-30 record it; "-" before)
  python3 - "$1" <<'EOF'
import json, re, sys
from collections import defaultdict
from pathlib import Path
rows = defaultdict(list)
for f in sorted(Path(sys.argv[1]).glob("*.json")):
    rows[re.sub(r"_[0-9]+$", "", f.stem)].append(json.loads(f.read_text()))
print(f"{'run':<16} {'n':>2} {'lag p99':>8} {'lag max':>8} {'pen-up p50':>11} {'engine p50':>11} {'preprocess':>11} "
      f"{'generator':>10} {'render':>7} {'erase max':>10}  ms")
for label, rs in rows.items():
    def mean(get):
        return sum(get(r) for r in rs) / len(rs)
    print(f"{label:<16} {len(rs):>2} {mean(lambda r: r['lag_ms']['p99']):8.1f} {mean(lambda r: r['lag_ms']['max']):8.1f} "
          f"{mean(lambda r: r['stroke_latency_summary_ms']['p50']):11.0f} {mean(lambda r: r['engine_ms']['p50']):11.1f} "
          f"{mean(lambda r: r['engine_stages_ms']['preprocess']['p50']):11.1f} "
          f"{mean(lambda r: r['engine_stages_ms']['generator']['p50']):10.1f} {mean(lambda r: r['render_thread_ms']['p50']):7.1f} "
          + (f"{mean(lambda r: r['lag_by_phase_ms']['erase']['max']):10.1f}"
             if all("erase" in r.get("lag_by_phase_ms", {}) for r in rs) else f"{'-':>10}")
          + ("" if all(not r["error"] for r in rs) else "  (an error: see the reports)"))
EOF
}

file_sessions() {  # the app under the pen with app/$2 of commit $3 (today's app otherwise, from git, first on
  # PYTHONPATH) and with today's, in turn: three sessions each of $4 (play_session or blank_session), reports
  # OUT50/$1/before_k.json and after_k.json, then their table (run it alone: it times)
  local before="$OUT50/$1_before" i
  rm -rf "$before"; mkdir -p "$before" "$OUT50/$1"
  cp -r app "$before/app"
  git show "$3:app/$2" > "$before/app/$2"
  for i in 1 2 3; do
    PYTHONPATH="$before" "$4" "$OUT50/$1/before_$i.json"
    "$4" "$OUT50/$1/after_$i.json"
  done
  session_table "$OUT50/$1"
}

with_engine() {  # $1 a commit ("" for the working tree), then a command: the command with that commit's engine/
  # (extracted from git) first on PYTHONPATH, so a step can measure an earlier engine beside today's
  local dir rc=0
  dir=$(mktemp -d /tmp/sketchmesh-engine-XXXXXX)
  [ -n "$1" ] && git archive "$1" engine | tar -x -C "$dir"
  PYTHONPATH="$dir${PYTHONPATH:+:$PYTHONPATH}" "${@:2}" || rc=$?
  rm -rf "$dir"
  return "$rc"
}

refine_engines() {  # $1 a folder, $2 and $3 commits ("" for the working tree): bench refine (the bundled pair as the app
  # runs it, mirror averaged, N = 0 and 3, clean and strong) with the engine of $2 and then of $3 (with_engine), in turn,
  # on the validation split (the choice), then the test split, into $1/{val,test}_{before,after}
  local split
  for split in val test; do
    with_engine "$2" sketchmesh bench refine --data "$DATA2" --split "$split" --max-samples "$SAMPLES2" --mirror-average \
      --steps 0 3 --out "$1/${split}_before"
    with_engine "$3" sketchmesh bench refine --data "$DATA2" --split "$split" --max-samples "$SAMPLES2" --mirror-average \
      --steps 0 3 --out "$1/${split}_after"
  done
}

busy_start() {  # two busy loops keep both cores loaded (another job on the artist's laptop) until busy_stop or the
  # script's end (the trap names their pids when it is set, so it works wherever the script stops)
  BUSY_PIDS=()
  for _ in 1 2; do python3 -c 'while True: pass' & BUSY_PIDS+=($!); done
  trap "kill ${BUSY_PIDS[*]} 2>/dev/null" EXIT
}

busy_stop() {
  kill "${BUSY_PIDS[@]}" 2>/dev/null; trap - EXIT
}

finetune_pair() {  # $1 a GPU-continued run, $2 the run it is compared with, $3 a prefix: both trained side by side on one
  # thread each with train7 into $3_gpu and $3_cpu, $4 iterations, $5 minutes at most
  [ -f "$DATA2/.cache/generated/normals16_mirror/info.json" ] || step generated-mirror-v9
  train7 "$1" "$3_gpu" "$4" "$5" 1 &
  train7 "$2" "$3_cpu" "$4" "$5" 1 &
  wait
}

gpucarry() {  # run $1's newest checkpoint without optimiser state (13 MB for today's predictor) and its config into
  # gpucarry/NAME, what training/gpu_predictor.sh starts from on a GPU machine (carry gpucarry and .whl)
  local name; name=$(basename "$1")
  mkdir -p "gpucarry/$name/checkpoints"
  cp "$1/config.json" "gpucarry/$name/"
  python3 -c "from training.loop.checkpoint import save_slim_copy as c, load_latest_checkpoint as l
it = l('$1')['iteration']; c('$1', f'gpucarry/$name/checkpoints/ckpt_{it:08d}.pt')"
}

log_summary() {  # $1: runs folder, then run names: iterations, wall time, median rate, and the silhouette term and
  # normal error over the first 100 and the last 1,000 iterations of each run's log.csv (runs without one are skipped)
  python3 - "$@" <<'EOF'
import csv, sys, numpy as np
from pathlib import Path
runs = Path(sys.argv[1])
for name in sys.argv[2:]:
    if not (runs / name / "log.csv").is_file():
        continue
    with open(runs / name / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    it = np.array([int(r["iteration"]) for r in rows])
    rate = np.median([float(r["it_per_s"]) for r in rows])
    walls = [float(r["wall_s"]) for r in rows]  # each sitting's clock starts again at 0 when a run resumes
    ends = [w for w, nxt in zip(walls, walls[1:] + [0.0]) if nxt < w]
    first = [r for r, i in zip(rows, it) if i <= it.min() + 99]
    last = [r for r, i in zip(rows, it) if i > it.max() - 1000]
    (sil0, nrm0), (sil, nrm) = [[np.mean([float(r[k]) for r in part]) for k in ("mesh_silhouette", "mesh_normal")]
                                for part in (first, last)]
    print(f"{name}: {it.max()} iterations, {float(rows[-1]['wall_s']) / 60:.1f} min, median {rate:.2f} it/s; "
          f"first 100: silhouette term {sil0:.4f}, normal error {nrm0:.1f}; last 1,000: silhouette term {sil:.4f}, "
          f"normal error {nrm:.1f}; {len(ends)} sitting(s), {sum(ends) / 60:.1f} min in all")
EOF
}

subset_data() {  # a dataset $2 (replaced) holding the shapes and views of the dataset $1 of the categories $3... alone:
  # its manifest filtered, its category folders linked (absolute), nothing copied
  rm -rf "$2"; mkdir -p "$2/shapes"
  python3 - "$1" "$2" "${@:3}" <<'PY'
import json, os, sys
from pathlib import Path
src, dst, cats = Path(sys.argv[1]).resolve(), Path(sys.argv[2]), set(sys.argv[3:])
m = json.load(open(src / "manifest.json"))
missing = cats - set(m["categories"])
if missing:
    sys.exit(f"subset_data: {src} has no category {sorted(missing)}")
m["categories"] = [c for c in m["categories"] if c in cats]
m["shapes"] = [r for r in m["shapes"] if r["category"] in cats]
m["views"] = [r for r in m["views"] if r["category"] in cats]
for c in m["categories"]:
    os.symlink(src / "shapes" / c, dst / "shapes" / c)
tmp = dst / "manifest.json.tmp"
tmp.write_text(json.dumps(m))
os.replace(tmp, dst / "manifest.json")
print(f"{dst}: {len(m['shapes'])} shapes, {len(m['views'])} views of {', '.join(m['categories'])}")
PY
}

router_table() {  # the routers of the model folders $2... on the dataset $1's generated images (ROUTER_TABLE_INPUTS
  # [normals16 normals16_mirror], every train row): category accuracy and, per threshold, each route's recall and false routes
  # (as the engine routes: the route whose categories' summed probability is largest and above the threshold), and the
  # expected gain on the 13-category mean, each route's categories' share x ROUTE_GAINS's gain of a drawing sent to its
  # specialist x recall - the other categories' share x 0.21 (what another drawing loses there, route-v36) x false
  # routes. ROUTE_GAINS ["legged=0.113 second=0.140 third=0.110": what the bundle's specialists gain on the clean test
  # drawings its router missed, oracle-clean-v55]. A router whose metadata sets route_mirror routes each drawing on the
  # mean of its and its flip's probabilities (the paired sets normals16 normals16_mirror), as the engine does
  ROUTER_TABLE_INPUTS=${ROUTER_TABLE_INPUTS:-normals16 normals16_mirror} python3 - "$@" <<'PY'
import os, sys
import numpy as np
from engine.models import load_router
from training.model.router import labelled_rows
gains = dict(kv.split("=") for kv in os.environ.get("ROUTE_GAINS", "legged=0.113 second=0.140 third=0.110").split())
data, folders = sys.argv[1], sys.argv[2:]
for folder in folders:
    r = load_router(os.path.join(folder, "router.onnx"), 2)
    sets, _, cats = labelled_rows(data, os.environ["ROUTER_TABLE_INPUTS"].split(), "train", r.categories)
    x = np.concatenate([g.rows(rows) for g, rows, _ in sets]).astype(np.float32)
    y = np.concatenate([lab for _, _, lab in sets])
    probs = np.concatenate([r.session.run(None, {r.input_name: x[i:i + 256]})[0] for i in range(0, len(x), 256)])
    if r.route_mirror:  # as the engine routes with mirror averaging on: each drawing on the mean with its flip's
        names_in = os.environ["ROUTER_TABLE_INPUTS"].split()
        if sorted(names_in) != ["normals16", "normals16_mirror"] or not np.array_equal(sets[0][1], sets[1][1]):
            sys.exit(f"router_table: {folder} routes on the drawing and its flip: give ROUTER_TABLE_INPUTS the paired "
                     "sets normals16 normals16_mirror")
        n = len(sets[0][1])
        probs = np.concatenate([(probs[:n] + probs[n:]) / 2] * 2)
    print(f"{folder}/router.onnx: {len(y)} drawings of {data}, category right {np.mean(probs.argmax(1) == y):.3f}")
    names = list(r.routes)
    sums = np.stack([probs[:, [cats.index(c) for c in r.routes[n]]].sum(1) for n in names], 1)
    truth = np.full(len(y), -1)
    for k, n in enumerate(names):
        truth[np.isin(y, [cats.index(c) for c in r.routes[n]])] = k
    for t in (0.5, 0.6, 0.7, 0.8, 0.9, 0.95):
        best = np.where(sums.max(1) > t, sums.argmax(1), -1)
        gain, parts = 0.0, []
        for k, n in enumerate(names):
            mine, others = truth == k, truth != k
            recall, false = np.mean(best[mine] == k), np.mean(best[others] == k)
            share = len(r.routes[n]) / len(cats)
            key = next((g for g in gains if g in n), None)
            gain += share * float(gains[key]) * recall - (1 - share) * 0.21 * false
            parts.append(f"{n.removeprefix('mesh_predictor_').removesuffix('.onnx')} {recall:.3f} / {false:.4f}")
        print(f"  threshold {t:.2f}: recall / false routes {'; '.join(parts)}; expected gain {gain:+.4f}")
PY
}

route_oracle() {  # a routed folder's eval JSON $1 (mirror only) and, for each route, "FILE=EVAL_JSON" $2...: the eval of
  # that route's predictor alone on its categories' drawings (the same views): the 13-category mean as routed, and as an
  # oracle router would route (every drawing of a route's categories to it, the others as routed), +- one standard
  # error over the test shapes, the paired difference, per category, and how much of it the missed drawings hold
  python3 - "$@" <<'PY'
import json, sys
from collections import defaultdict
res = json.load(open(sys.argv[1])); col = res["columns"][0]
only = {}  # (category, shape, view) -> iou of the route's predictor alone
cats_of = {}
for arg in sys.argv[2:]:
    name, path = arg.split("=", 1)
    r2 = json.load(open(path)); c2 = r2["columns"][0]
    for r in r2["rows"]:
        cats_of[r["category"]] = name
        for v in r["per_view"]:
            only[(r["category"], r["shape_id"], v["view"])] = v["iou"][c2]
routed, oracle = defaultdict(list), defaultdict(list)
missed = defaultdict(lambda: [0, 0, 0.0])  # category -> [drawings, missed, summed gain on the missed]
for r in res["rows"]:
    cat = r["category"]
    a, b = [], []
    for v in r["per_view"]:
        x = v["iou"][col]; y = x
        if cat in cats_of:
            key = (cat, r["shape_id"], v["view"])
            if key not in only:
                sys.exit(f"route_oracle: {key} has no score from {cats_of[cat]}'s eval")
            y = only[key]
            missed[cat][0] += 1
            if v["routes"][col]["route"] != cats_of[cat]:
                missed[cat][1] += 1; missed[cat][2] += y - x
        a.append(x); b.append(y)
    routed[cat].append(sum(a) / len(a)); oracle[cat].append(sum(b) / len(b))
def mean_se(per):
    m = sum(sum(x) / len(x) for x in per.values()) / len(per)
    v = sum(sum((y - sum(x) / len(x)) ** 2 for y in x) / (len(x) - 1) / len(x) for x in per.values() if len(x) > 1)
    return m, v ** 0.5 / len(per)
diff = {c: [o - r for o, r in zip(oracle[c], routed[c])] for c in routed}
for label, per in (("as routed", routed), ("oracle routing", oracle), ("oracle minus routed (paired)", diff)):
    m, se = mean_se(per)
    print(f"{label}: {m:+.4f} +- {se:.4f} over {len(per)} categories")
for c in sorted(missed):
    n, k, g = missed[c]
    print(f"  {c} -> {cats_of[c]}: {sum(routed[c]) / len(routed[c]):.3f} routed, {sum(oracle[c]) / len(oracle[c]):.3f} "
          f"oracle; {k} of {n} drawings missed, the route's predictor {g / max(k, 1):+.3f} on them on average")
PY
}

step() {
  EVAL_EXTRA=()  # every step starts from the clean case: a step that sets no case (overfit-*) inherits none from the one before
  case "$1" in
    data)
      sketchmesh data --source procedural --shapes-per-category 30 --workers 2 --out "$DATA" ;;
    normals)  # width 32: compared in the error-against-run-time table (too large to bundle, see the card)
      sketchmesh train normals --data "$DATA" --out "$RUNS/normals32" --base-channels 32 --batch 4 "${GENERATOR[@]}" \
        --iters "$GEN_ITERS" --threads "$THREADS" --ckpt-every 100 ;;
    normals16)  # width 16: the bundled generator
      sketchmesh train normals --data "$DATA" --out "$RUNS/normals16" --base-channels 16 --batch 4 "${GENERATOR[@]}" \
        --iters "$GEN_ITERS" --threads "$THREADS" --ckpt-every 100 ;;
    mesh)
      sketchmesh train mesh --normal-edges --data "$DATA" --out "$RUNS/mesh_full" --batch 8 "${PREDICTOR[@]}" \
        --normal-region target --iters "$MESH_ITERS" --threads "$THREADS" --ckpt-every 250 --val-every 1000 ;;
    silhouette)  # the Table-1 baseline: the same run with the normal-loss weight 0
      sketchmesh train mesh --normal-edges --data "$DATA" --out "$RUNS/mesh_silhouette" --batch 8 "${PREDICTOR[@]}" \
        --normal-region target --lambda-n 0 --iters "$MESH_ITERS" --threads "$THREADS" --ckpt-every 250 --val-every 1000 ;;
    paper-normal)  # the paper's Eq. 2 over the whole image, for the model card's finding (short run)
      sketchmesh train mesh --normal-edges --data "$DATA" --out "$RUNS/mesh_paper_normal" --batch 8 "${PREDICTOR[@]}" \
        --normal-region image --iters 250 --threads "$THREADS" --log-every 50 --ckpt-every 250 --val-every 250 ;;
    clamp-trial)  # the next change to try: linear (clamped) local offsets instead of tanh (short run)
      sketchmesh train mesh --normal-edges --data "$DATA" --out "$RUNS/mesh_clamp" --batch 8 --predictor-arch softras --predictor-channels 32 \
        --predictor-hidden 512 --predictor-latent 256 --predictor-local-bound clamp --lr-mesh 1e-4 --lr-warmup 0 \
        --extra-views 1 --normal-region target --iters 1000 --threads 2 --log-every 50 \
        --ckpt-every 250 --val-every 500 ;;
    joint)
      sketchmesh train joint --normal-edges --data "$DATA" --out "$RUNS/joint" --base-channels 16 --batch 4 "${GENERATOR[@]}" "${PREDICTOR[@]}" \
        --normal-region target --init-normals "$RUNS/normals16" --init-mesh "$RUNS/mesh_full" \
        --iters "$JOINT_ITERS" --threads 2 --ckpt-every 50 --val-every 250 ;;
    export)  # the bundled pair (joint fine-tune; width-16 generator float32, predictor int8) and the
             # variants before the fine-tune, for the width comparison
      sketchmesh export "$RUNS/joint" -o "$OUT/models_fp32"
      sketchmesh export "$RUNS/joint" -o "$OUT/models_int8" --quantize int8
      sketchmesh export "$RUNS/mesh_full" --generator-run "$RUNS/normals32" -o "$OUT/models_w32_pretrained"
      sketchmesh export "$RUNS/mesh_full" --generator-run "$RUNS/normals16" -o "$OUT/models_w16_pretrained" ;;
    eval)
      sketchmesh eval "${CENTRES[@]}" "$RUNS/mesh_full" --data "$DATA" --generator-run "$RUNS/normals16" \
        --baseline-run "$RUNS/mesh_silhouette" --baseline-run "$RUNS/joint" \
        --max-samples "$SAMPLES" --threads 2 --out "$OUT/eval_clean" ;;
    eval-strong)  # the same sketches with strong hand-drawn augmentation (broken lines, jitter)
      sketchmesh eval "${CENTRES[@]}" "$RUNS/mesh_full" --data "$DATA" --generator-run "$RUNS/normals16" \
        --baseline-run "$RUNS/mesh_silhouette" --baseline-run "$RUNS/joint" --augment-strength 1.0 \
        --max-samples "$SAMPLES" --threads 2 --out "$OUT/eval_strong" ;;
    eval-gt)  # the predictors on ground-truth normal images: the mesh step alone, without the generator
      sketchmesh eval "${CENTRES[@]}" "$RUNS/mesh_full" --data "$DATA" --gt-normals --baseline-run "$RUNS/mesh_silhouette" \
        --max-samples "$SAMPLES" --threads 2 --out "$OUT/eval_gt_normals" ;;
    tradeoff)
      sketchmesh bench tradeoff "${CENTRES[@]}" --data "$DATA" --variant "w16-joint=$OUT/models_fp32" \
        --variant "w32=$OUT/models_w32_pretrained" --variant "w16=$OUT/models_w16_pretrained" \
        --precisions fp32 int8-predictor int8 --levels 2 3 4 --bundled w16-joint:int8-predictor \
        --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT/tradeoff" ;;
    gallery)
      sketchmesh gallery --data "$DATA" --models assets/models -o "$OUT/gallery.png" ;;
    docs)  # the README's history figure (the variants step's plot); docs-v2 makes the others
      mkdir -p docs
      cp "$OUT/variants/variants.png" docs/variants.png ;;
    overfit)  # issue 14's check: the default predictor on 8 training shapes, 20 min, against direct fits of them
      sketchmesh bench overfit --set normal_edges=true "${CENTRES[@]}" --out "$RUNS/overfit" --minutes 20 --iters 4700 --fit-smoothing 16 ;;
    variants)  # predictor configurations at equal wall time on the test split (ground-truth normals in)
      # (measured before the cosine decay became the default: these runs keep the constant rate)
      sketchmesh bench variants --set normal_edges=true "${CENTRES[@]}" --data "$DATA" --out "$OUT/variants" --minutes 8 --points 4 --max-samples 156 \
        --set lr_schedule=constant \
        --variant default --variant k1:extra_views=1 --variant k7:extra_views=7 \
        --variant "softras-paper:predictor_arch=softras,lr_mesh=1e-4,lr_warmup=0,extra_views=1,predictor_local_bound=tanh" \
        --variant 3d-diagnostic:supervision=3d
      # the default alone, continued to 20 minutes (same 2-minute chunks)
      sketchmesh bench variants --set normal_edges=true "${CENTRES[@]}" --data "$DATA" --out "$OUT/variants" --minutes 20 --points 10 --max-samples 156 \
        --set lr_schedule=constant --variant default
      # the silhouette-gradient variants (constant rate, like the default they are compared with) and
      # the cosine decay over what 8 minutes hold
      sketchmesh bench variants --set normal_edges=true "${CENTRES[@]}" --data "$DATA" --out "$OUT/variants" --minutes 8 --points 4 --max-samples 156 \
        --set lr_schedule=constant --variant far8:edge_range=8 --variant soft:silhouette=soft
      sketchmesh bench variants --set normal_edges=true "${CENTRES[@]}" --data "$DATA" --out "$OUT/variants" --minutes 8 --points 4 --max-samples 156 \
        --variant cosine:lr_schedule=cosine,iters=1780
      # the cosine default over two hours (resumable: a later call continues the finished chunks)
      sketchmesh bench variants --set normal_edges=true "${CENTRES[@]}" --data "$DATA" --out "$OUT/variants" --minutes 120 --points 12 --max-samples 156 \
        --variant cosine120:lr_schedule=cosine,iters=30000 ;;
    data-v2)  # 1,300 shapes x 12 azimuths x 4 elevations (0, 15, 30, 45 degrees): 62,400 views
      sketchmesh data --source procedural --shapes-per-category 100 --views 12 --elevations 0 15 30 45 \
        --workers 2 --out "$DATA2" ;;
    data-v2-eval)  # data-v2's validation and test shapes only, what every measurement reads (eval, bench refine, compare,
      # tradeoff): the first step on a bare machine, a fifth of data-v2's rendering; data-v2 later adds the training
      # shapes to the same folder
      sketchmesh data --source procedural --shapes-per-category 100 --views 12 --elevations 0 15 30 45 \
        --splits val test --workers 2 --out "$DATA2" ;;
    normals-v2)  # the resize generator, width 16 (one thread)
      sketchmesh train normals --data "$DATA2" --out "$RUNS2/normals16" --base-channels 16 --batch 4 \
        --iters "$GEN2_ITERS" --threads 1 --ckpt-every 100 ;;
    normals8-v2)  # the same at width 8: the other point of the error-against-run-time table
      sketchmesh train normals --data "$DATA2" --out "$RUNS2/normals8" --base-channels 8 --batch 4 \
        --iters "$GEN2_ITERS" --threads 1 --ckpt-every 100 ;;
    mesh-v2)  # the default predictor and loss (cosine decay over MESH2_ITERS; one thread)
      sketchmesh train mesh --normal-edges --data "$DATA2" --out "$RUNS2/mesh_full" --iters "$MESH2_ITERS" --threads 1 \
        --ckpt-every 250 --val-every 2000 ;;
    silhouette-v2)  # the Table-1 baseline: mesh-v2 with the normal-loss weight 0
      sketchmesh train mesh --normal-edges --data "$DATA2" --out "$RUNS2/mesh_silhouette" --iters "$MESH2_ITERS" --threads 1 \
        --lambda-n 0 --ckpt-every 250 --val-every 2000 ;;
    joint-v2)  # end-to-end fine-tune from the two pre-trainings; the predictor at 1/20 of its pre-training rate
      sketchmesh train joint --normal-edges --data "$DATA2" --out "$RUNS2/joint" --base-channels 16 --batch 4 \
        --init-normals "$RUNS2/normals16" --init-mesh "$RUNS2/mesh_full" --lr-mesh 1e-4 --lr-warmup 0 \
        --iters "$JOINT2_ITERS" --threads 2 --ckpt-every 50 --val-every 250 ;;
    predictor-on-generated-v2)  # experiment: the silhouette-only predictor fine-tuned on the generator's own normal
      # images (generator and discriminator frozen: learning rate 1e-12), to measure the gap between ground-truth
      # and generated normals (joint mode, batch 8, 2 threads, 25 minutes)
      sketchmesh train joint --normal-edges --data "$DATA2" --out "$RUNS2/predictor_on_generated" --base-channels 16 --batch 8 \
        --init-normals "$RUNS2/normals16" --init-mesh "$RUNS2/mesh_silhouette" --lambda-n 0 --lr-g 1e-12 --lr-d 1e-12 \
        --lr-mesh 2e-4 --lr-warmup 0 --iters 1200 --max-minutes 25 --threads 2 --ckpt-every 100 --val-every 0
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/predictor_on_generated" --data "$DATA2" --baseline-run "$RUNS2/mesh_silhouette" \
        --generator-run "$RUNS2/normals16" --max-samples "$SAMPLES2" --threads 2 --out "$OUT2/eval_predictor_on_generated" ;;
    ceiling-v2)  # diagnostic: the silhouette-only predictor continued for CEIL_MINUTES [50] of wall time side by side
      # (one thread each, cosine over 8,000 iterations from Adam 1e-3) with its 2D loss and with 3D supervision
      # (Chamfer distance to the true surface: a diagnostic ceiling of the network, never the method), then both
      # evaluated on ground-truth normal images: is the predictor limited by its 2D signal or by its shape space?
      local m=${CEIL_MINUTES:-50} cont=(--data "$DATA2" --init-mesh "$RUNS2/mesh_silhouette" --lambda-n 0 --lr-mesh 1e-3
        --iters 8000 --threads 1 --ckpt-every 250 --val-every 0 --quiet)
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/continued_2d" --max-minutes "$m" &
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/continued_3d" --supervision 3d --max-minutes "$m" &
      wait
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/continued_2d" --data "$DATA2" --gt-normals --baseline-run "$RUNS2/continued_3d" \
        --baseline-run "$RUNS2/mesh_silhouette" --max-samples "$SAMPLES2" --threads 2 --out "$OUT2/eval_ceiling"
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/continued_2d" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/mesh_silhouette" --max-samples "$SAMPLES2" --threads 2 --out "$OUT2/eval_continued_clean" ;;
    generated-v4)  # the predictor's input as the app sees it: the bundled generator (the third models' fp32
      # export of RUNS2/normals16) over the half-strength hand-drawn sketch of every training view (14 min, 2 processes)
      [ -f "$OUT2/models_silhouette/generator.onnx" ] || step export-v2
      sketchmesh data generated "$DATA2" --models "$OUT2/models_silhouette" --name normals16 --workers 2 ;;
    predictor-v4)  # the third models' predictor continued (ceiling-v2's continued_2d) for V4_MINUTES [45] of wall
      # time side by side, one thread each: on ground-truth normal images (the comparison) and on the generator's
      # images of the training sketches (generated-v4; targets still the true images and silhouettes)
      local m=${V4_MINUTES:-45} cont=(--data "$DATA2" --init-mesh "$RUNS2/continued_2d" --lambda-n 0 --lr-mesh 5e-4
        --iters 8000 --threads 1 --ckpt-every 250 --val-every 0 --quiet)
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/v4_true_inputs" --max-minutes "$m" &
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/v4_generated_inputs" --input-normals normals16 --max-minutes "$m" &
      wait ;;
    predictor-v4-more)  # the winner of predictor-v4 (generated inputs: +0.036 over true inputs from clean sketches)
      # continued on the same generated inputs for V4B_MINUTES [40] more, alone on two threads
      sketchmesh train mesh --normal-edges --data "$DATA2" --init-mesh "$RUNS2/v4_generated_inputs" --input-normals normals16 \
        --lambda-n 0 --lr-mesh 5e-4 --iters 9000 --threads 2 --ckpt-every 250 --val-every 0 --quiet \
        --out "$RUNS2/v4_generated_more" --max-minutes "${V4B_MINUTES:-40}" ;;
    generated-v5)  # a second drawing of every training view through the same generator: seed 1, the
      # augmentation at full strength (what eval-strong draws; the first set is seed 0, half strength)
      [ -f "$OUT2/models_silhouette/generator.onnx" ] || step export-v2
      sketchmesh data generated "$DATA2" --models "$OUT2/models_silhouette" --name normals16_s1 --augment-strength 1.0 \
        --seed 1 --workers 2 ;;
    predictor-v5)  # equal time: the fourth bundled predictor (v4_generated_more) continued for 6,000 iterations
      # (V5_MINUTES [22] at most), alone on two threads, once on the first generated set only (the control,
      # v4_generated_last) and once on both sets (v5_two_sets); the same seed, schedule and rate
      local cont=(--data "$DATA2" --init-mesh "$RUNS2/v4_generated_more" --lambda-n 0 --lr-mesh 3e-4 --iters 6000
        --threads 2 --ckpt-every 250 --val-every 0 --quiet --max-minutes "${V5_MINUTES:-22}")
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/v4_generated_last" --input-normals normals16
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/v5_two_sets" --input-normals normals16,normals16_s1
      # and, on the first set only, with the predictor's fully connected layers doubled (code 256 -> 512,
      # decoder 512 -> 1024; widened so it starts as the same function): capacity, since the predictor
      # scores 0.44 on training sketches against 0.73 for direct fits
      sketchmesh train mesh --normal-edges "${cont[@]}" --out "$RUNS2/v5_wide" --input-normals normals16 \
        --predictor-latent 512 --predictor-hidden 1024
      # and the full loss: the paper's normal term (weight 0.002) back on, the rest as the control (issue 16's
      # full-minus-silhouette comparison on these runs)
      sketchmesh train mesh --normal-edges "${cont[@]}" --lambda-n 0.002 --out "$RUNS2/v5_full" --input-normals normals16 ;;
    eval-v5|eval-strong-v5|eval-side-v5|eval-gt-v5)  # the wide and two-set runs against the one-set control and
      # their start (the fourth bundled predictor)
      eval_case "$1"
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/v5_wide" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v5_two_sets" --baseline-run "$RUNS2/v5_full" --baseline-run "$RUNS2/v4_generated_last" \
        --baseline-run "$RUNS2/v4_generated_more" "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 --out "$OUT5/$EVAL_NAME" ;;
    logs-v5)  # what the trials' training logs say: rate and loss terms over each run's last 1,000 iterations,
      # and how far the wide run's new head columns grew (norm against the old columns')
      python3 - "$RUNS2" <<'EOF'
import csv, sys, numpy as np
from pathlib import Path
from training.loop.checkpoint import load_latest_checkpoint
runs = Path(sys.argv[1])
for name in ("v4_true_inputs", "v4_generated_last", "v5_two_sets", "v5_wide", "v5_full"):
    with open(runs / name / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    it = np.array([int(r["iteration"]) for r in rows])
    last = [r for r, i in zip(rows, it) if i > it.max() - 1000]
    terms = ", ".join(f"{k} {np.mean([float(r[k]) for r in last]):.4g}" for k in ("mesh_total", "mesh_silhouette", "mesh_normal"))
    print(f"{name}: {it.max()} iterations, {it.max() / float(rows[-1]['wall_s']):.2f} it/s; last 1,000: {terms}")
head = load_latest_checkpoint(runs / "v5_wide")["models"]["predictor"]["local_head.weight"]
old = int(load_latest_checkpoint(runs / "v4_generated_more")["models"]["predictor"]["local_head.weight"].shape[1])
print(f"v5_wide: new head columns' norm / old columns' norm = {float(head[:, old:].norm() / head[:, :old].norm()):.3f}")
EOF
      ;;
    eval-train-v5)  # the same from clean sketches of training views: how well the predictors fit what they
      # trained on (against the direct fits' 0.73 of `bench fit`)
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/v5_wide" --data "$DATA2" --split train --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_generated_last" --baseline-run "$RUNS2/continued_2d" --no-retrieval \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT5/eval_train" ;;
    refine-v6)  # refine-v2 (the app's outline refinement, bundled models) with the surface measure
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --out "$OUT6/refine" ;;
    thin-v6)  # why the measure changed: per category, how many of the 156 test sketches' ground-truth shapes have
      # no solid cell at all by cell centres, and by the surface measure
      python3 - "$DATA2" "$SAMPLES2" <<'EOF'
import sys
from collections import Counter
from pathlib import Path
import numpy as np
from training.data.dataset import ShapeViewDataset
from training.evaluation.metrics import solid_voxels
ds = ShapeViewDataset(Path(sys.argv[1]), "test", extra_views=0, augment_strength=0.0)
idx = np.arange(len(ds))
n = int(sys.argv[2])
if n and n < len(idx):  # the samples sketchmesh eval --max-samples N scores
    idx = idx[np.unique(np.linspace(0, len(idx) - 1, n).round().astype(int))]
total, empty = Counter(), {False: Counter(), True: Counter()}
for i in idx:
    item = ds[int(i)]
    cat, sid = item["category"], item["shape_id"]
    mesh = ds.load_mesh(cat, sid)
    total[cat] += 1
    for surface in (False, True):
        empty[surface][cat] += int(not solid_voxels(mesh, 32, surface).any())
print("category: samples, ground truths with no solid cell by centres / by the surface measure")
for cat in sorted(total):
    print(f"{cat}: {total[cat]}, {empty[False][cat]} / {empty[True][cat]}")
EOF
      ;;
    variety-v6)  # how near a held-out shape's nearest training shape is (the bound on retrieval), surface measure
      mkdir -p "$OUT6"
      sketchmesh bench variety --shapes-per-category 100 --quiet --json "$OUT6/variety.json" ;;
    fit-v6)  # the direct-fit ceiling (one mesh optimised per shape, 8 views) on the first training shape of every
      # category, surface measure
      mkdir -p "$OUT6"
      sketchmesh bench fit --procedural 1 --smoothing 16 --json "$OUT6/fit.json" ;;
    predictor-v6)  # the encoder's depth at equal time: the fourth bundled predictor continued, alone on two threads,
      # with one residual block (two 3x3 convolutions) after each strided convolution, deepened so it starts as the
      # same function; against trials-v5's control (6,000 iterations in 19.4 min). The blocks slow a step from 5.2 to
      # 3.2 iterations per second, so DEEP_ITERS [3400] (17.8 min) fits the same time with a complete cosine decay
      sketchmesh train mesh --normal-edges --data "$DATA2" --init-mesh "$RUNS2/v4_generated_more" --lambda-n 0 --lr-mesh 3e-4 \
        --iters "${DEEP_ITERS:-3400}" --threads 2 --ckpt-every 250 --val-every 0 --quiet --max-minutes "${V5_MINUTES:-22}" \
        --out "$RUNS2/v6_deep" --input-normals normals16 --predictor-blocks 1 ;;
    full-interior-v6)  # the full loss with the normal term's gradient kept off the outline (--no-normal-edges: the
      # normal image orients the surface, the silhouette term alone moves the outline), trials-v5's v5_full otherwise
      sketchmesh train mesh --data "$DATA2" --init-mesh "$RUNS2/v4_generated_more" --lambda-n 0.002 --lr-mesh 3e-4 \
        --iters 6000 --threads 2 --ckpt-every 250 --val-every 0 --quiet --max-minutes "${V5_MINUTES:-22}" \
        --out "$RUNS2/v6_full_interior" --input-normals normals16 --no-normal-edges ;;
    full-interior-x5-v6)  # the same with the normal weight 5x the paper's (0.01): off the outline, does more help?
      sketchmesh train mesh --data "$DATA2" --init-mesh "$RUNS2/v4_generated_more" --lambda-n 0.01 --lr-mesh 3e-4 \
        --iters 6000 --threads 2 --ckpt-every 250 --val-every 0 --quiet --max-minutes "${V5_MINUTES:-22}" \
        --out "$RUNS2/v6_full_interior_x5" --input-normals normals16 --no-normal-edges ;;
    eval-interior-v6|eval-interior-strong-v6|eval-interior-side-v6|eval-interior-gt-v6)  # it against the full
      # loss of trials-v5 and the silhouette-only control
      eval_case "${1/interior-/}"
      local x5=()  # the 5x-weight run where it exists
      [ ! -d "$RUNS2/v6_full_interior_x5" ] || x5=(--baseline-run "$RUNS2/v6_full_interior_x5")
      sketchmesh eval "$RUNS2/v6_full_interior" --data "$DATA2" --generator-run "$RUNS2/normals16" "${x5[@]}" \
        --baseline-run "$RUNS2/v5_full" --baseline-run "$RUNS2/v4_generated_last" --no-retrieval "${EVAL_EXTRA[@]}" \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT6/interior_$EVAL_NAME" ;;
    interior-v6)  # the sixth session's second trial: full minus silhouette-only with the normal term off the outline
      RUNS2=runs/gpu; OUT2=out/v3
      [ -d "$RUNS2/v5_full" ] || step trials-v5
      for s in full-interior-v6 full-interior-x5-v6 logs-v6 eval-interior-v6 eval-interior-strong-v6 eval-interior-side-v6 \
               eval-interior-gt-v6 gallery-interior-v6; do
        step "$s"
      done ;;
    predictor-v7)  # the candidate next predictor: interior-v6's run (the normal term off the outline) trained on for
      # V7_ITERS [9000] more iterations (V7_MINUTES [45] at most, two threads; RUNS2=runs/gpu as interior-v6 sets it);
      # resumes, nothing measured yet
      sketchmesh train mesh --data "$DATA2" --init-mesh "$RUNS2/v6_full_interior" --lambda-n 0.002 --lr-mesh 3e-4 \
        --iters "${V7_ITERS:-9000}" --threads 2 --ckpt-every 250 --val-every 0 --quiet \
        --max-minutes "${V7_MINUTES:-45}" --out "$RUNS2/v7_interior_more" --input-normals normals16 --no-normal-edges ;;
    gallery-interior-v6)  # the full loss off the outline as the app would run it (int8 predictor, the bundled
      # generator), on gallery-v2's test shapes: to look at beside docs/gallery.png (the bundled pair)
      sketchmesh export "$RUNS2/v6_full_interior" --generator-run "$RUNS2/normals16" -o "$OUT6/models_interior_int8" \
        --quantize int8
      sketchmesh gallery --data "$DATA2" --models "$OUT6/models_interior_int8" -o "$OUT6/gallery_interior.png" ;;
    logs-v6)  # the sixth session's runs' training logs against the control's (rate, silhouette term and normal
      # error over the last 1,000 iterations) and how far the deeper run's gates opened
      python3 - "$RUNS2" <<'EOF'
import csv, sys, numpy as np
from pathlib import Path
from training.loop.checkpoint import load_latest_checkpoint
runs = Path(sys.argv[1])
for name in ("v4_generated_last", "v5_full", "v6_deep", "v6_full_interior", "v6_full_interior_x5"):
    if not (runs / name / "log.csv").is_file():
        continue
    with open(runs / name / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    it = np.array([int(r["iteration"]) for r in rows])
    last = [r for r, i in zip(rows, it) if i > it.max() - 1000]
    sil, nrm = (np.mean([float(r[k]) for r in last]) for k in ("mesh_silhouette", "mesh_normal"))
    print(f"{name}: {it.max()} iterations in {float(rows[-1]['wall_s']) / 60:.1f} min "
          f"({it.max() / float(rows[-1]['wall_s']):.2f} it/s); last 1,000: silhouette term {sil:.4f}, "
          f"normal error {nrm:.1f}")
buffers = ("running_mean", "running_var", "num_batches_tracked", "basis")
for name in ("v4_generated_last", "v6_deep"):
    if (runs / name).is_dir():
        sd = load_latest_checkpoint(runs / name)["models"]["predictor"]
        count = sum(v.numel() for k, v in sd.items() if not k.endswith(buffers))
        print(f"{name}: {count:,} predictor parameters")
        if name == "v6_deep":
            print("v6_deep gates:", ", ".join(f"{k} {float(v):+.5f}" for k, v in sd.items() if k.endswith(".gain")))
EOF
      ;;
    eval-deep-v6|eval-deep-strong-v6|eval-deep-side-v6|eval-deep-gt-v6)  # the deeper encoder against the control
      eval_case "${1/deep-/}"
      sketchmesh eval "$RUNS2/v6_deep" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_generated_last" --no-retrieval "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" \
        --threads 2 --out "$OUT6/deep_$EVAL_NAME" ;;
    eval-deep-train-v6)  # and on clean sketches of training views (does depth fit the training set better?)
      sketchmesh eval "$RUNS2/v6_deep" --data "$DATA2" --split train --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_generated_last" --no-retrieval --max-samples "$SAMPLES2" --threads 2 \
        --out "$OUT6/deep_eval_train" ;;
    val-v7)  # the choice of the fifth predictor, on the validation split (clean sketches): predictor-v7's run against
      # interior-v6's (where it started) and the fourth bundled predictor; the test split is only measured after
      sketchmesh eval "$RUNS2/v7_interior_more" --data "$DATA2" --split val --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v6_full_interior" --baseline-run "$RUNS2/v4_generated_more" --no-retrieval \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT7/val_clean" ;;
    eval-v7|eval-strong-v7|eval-side-v7|eval-gt-v7)  # the chosen predictor (PRED7 [v7_interior_more]) on the test
      # split against interior-v6's run, the fourth bundled predictor and retrieval
      eval_case "$1"
      sketchmesh eval "$RUNS2/${PRED7:-v7_interior_more}" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v6_full_interior" --baseline-run "$RUNS2/v4_generated_more" "${EVAL_EXTRA[@]}" \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT7/$EVAL_NAME" ;;
    eval-train-v7)  # the same from clean sketches of training views (against the direct fits' 0.763 of fit-v6)
      sketchmesh eval "$RUNS2/${PRED7:-v7_interior_more}" --data "$DATA2" --split train --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_generated_more" --no-retrieval --max-samples "$SAMPLES2" --threads 2 \
        --out "$OUT7/eval_train" ;;
    export-v7)  # the chosen predictor with the third and fourth models' generator; the int8 predictor is the bundled one
      sketchmesh export "$RUNS2/${PRED7:-v7_interior_more}" --generator-run "$RUNS2/normals16" -o "$OUT7/models_fp32"
      sketchmesh export "$RUNS2/${PRED7:-v7_interior_more}" --generator-run "$RUNS2/normals16" -o "$OUT7/models_int8" \
        --quantize int8
      [ -d "$OUT4/models_fp32" ] || step export-v4 ;;
    tradeoff-v7)  # error against run time in the app's engine: the fifth pair beside the fourth's and width 8, surface
      # measure (run it alone: it times)
      sketchmesh bench tradeoff --data "$DATA2" --variant "w16-v7=$OUT7/models_fp32" --variant "w16-v4=$OUT4/models_fp32" \
        --variant "w8-full=$OUT2/models_w8_pretrained" --precisions fp32 int8-predictor int8 --levels 2 3 4 \
        --bundled w16-v7:int8-predictor --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT7/tradeoff" ;;
    control-v7)  # predictor-v7's silhouette-only control: trials-v5's equal-time control (v4_generated_last, the
      # same start and 6,000 iterations against interior-v6's 5,720) trained on for the same 9,000 iterations with
      # the same schedule, normal weight 0 (V7_MINUTES [45] at most, two threads; resumes)
      sketchmesh train mesh --normal-edges --data "$DATA2" --init-mesh "$RUNS2/v4_generated_last" --lambda-n 0 --lr-mesh 3e-4 \
        --iters "${V7_ITERS:-9000}" --threads 2 --ckpt-every 250 --val-every 0 --quiet \
        --max-minutes "${V7_MINUTES:-45}" --out "$RUNS2/v7_silhouette_more" --input-normals normals16 ;;
    eval-control-v7|eval-control-strong-v7|eval-control-side-v7|eval-control-gt-v7)  # full minus silhouette-only
      # after the longer training: predictor-v7 against control-v7
      eval_case "${1/control-/}"
      sketchmesh eval "$RUNS2/v7_interior_more" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v7_silhouette_more" --no-retrieval "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" \
        --threads 2 --out "$OUT7/control_$EVAL_NAME" ;;
    logs-v7)  # predictor-v7's and control-v7's training logs: rate, and the silhouette term and normal error over
      # their last 1,000 iterations (where a run was stopped and resumed, wall time counts the invocations' own)
      log_summary "$RUNS2" v6_full_interior v4_generated_last v7_interior_more v7_silhouette_more ;;
    logs-v8)  # the v8 runs' training logs: rate and wall time, the silhouette term and normal error over their first 100
      # and last 1,000 iterations
      log_summary "$RUNS8" v8_more v8_mirror v8_more2 ;;
    models-fifth-v8)  # the fifth bundled pair as shipped (git FIFTH [5b01fa5]) into OUT8/models_fifth: what the v8
      # steps start from, on any machine (its training runs stayed on the machine that trained it)
      models_from_git "${FIFTH:-5b01fa5}" "$OUT8/models_fifth" ;;
    generated-v8)  # generated-v4's inputs from the fifth pair's generator (the same generator: the same images), 14 min
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      sketchmesh data generated "$DATA2" --models "$OUT8/models_fifth" --name normals16 --workers 2 ;;
    import-v8)  # the fifth pair back as training runs (RUNS8/fifth/generator, RUNS8/fifth/predictor): weights from the
      # ONNX files, the predictor's batch norms calibrated on 256 of its generated training inputs, parity checked
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      [ -f "$RUNS8/fifth/predictor/config.json" ] || \
        sketchmesh import-models "$OUT8/models_fifth" --out "$RUNS8/fifth" --data "$DATA2" --threads 2 ;;
    predictor-v8)  # two candidates for the sixth predictor at equal wall time, side by side on one thread each, from
      # the imported fifth predictor with its loss (normal weight 0.002 off the outline), Adam 3e-4 cosine over
      # V8_ITERS [7000] (V8_MINUTES [55] at most; resumes): trained on as it is (v8_more) and with half of every
      # batch mirrored (v8_mirror, --mirror 0.5)
      [ -f "$RUNS8/fifth/predictor/config.json" ] || step import-v8
      local v8=(--data "$DATA2" --init-mesh "$RUNS8/fifth/predictor" --lambda-n 0.002 --lr-mesh 3e-4
        --iters "${V8_ITERS:-7000}" --threads 1 --ckpt-every 250 --val-every 0 --quiet
        --max-minutes "${V8_MINUTES:-55}" --input-normals normals16 --no-normal-edges)
      sketchmesh train mesh "${v8[@]}" --out "$RUNS8/v8_more" &
      sketchmesh train mesh "${v8[@]}" --mirror 0.5 --out "$RUNS8/v8_mirror" &
      wait ;;
    predictor-v8-more)  # predictor-v8's plain run (v8_more: +0.004 on the validation split, the mirrored one +0.001)
      # trained on alone on two threads: Adam 2e-4 cosine over V8B_ITERS [9000] (V8B_MINUTES [33] at most; resumes)
      sketchmesh train mesh --data "$DATA2" --init-mesh "$RUNS8/v8_more" --lambda-n 0.002 --lr-mesh 2e-4 \
        --iters "${V8B_ITERS:-9000}" --threads 2 --ckpt-every 250 --val-every 0 --quiet \
        --max-minutes "${V8B_MINUTES:-33}" --input-normals normals16 --no-normal-edges --out "$RUNS8/v8_more2" ;;
    val-v8-more)  # the choice of the sixth predictor on the validation split: v8_more2 against v8_more and the fifth
      sketchmesh eval "$RUNS8/v8_more2" --data "$DATA2" --split val --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS8/v8_more" --baseline-run "$RUNS8/fifth/predictor" --no-retrieval \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT8/val_more" ;;
    eval-v8b|eval-strong-v8b|eval-side-v8b|eval-gt-v8b)  # the chosen sixth predictor (PRED8 [v8_more2]) on the test split
      # against v8_more and the fifth (imported), into OUT8/final (retrieval: eval-*-v7's, the same samples)
      eval_case "$1"
      sketchmesh eval "$RUNS8/${PRED8:-v8_more2}" --data "$DATA2" --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS8/v8_more" --baseline-run "$RUNS8/fifth/predictor" --no-retrieval "${EVAL_EXTRA[@]}" \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT8/final/$EVAL_NAME" ;;
    export-v8)  # the chosen predictor as float32 and int8 (the bundled one), each beside the fifth pair's generator file
      export_pair "$RUNS8/${PRED8:-v8_more2}" "$OUT8/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v8)  # error against run time in the app's engine: the sixth pair at each precision and template level
      # (run it alone: it times)
      sketchmesh bench tradeoff --data "$DATA2" --variant "w16-v8=$OUT8/final/models_fp32" \
        --precisions fp32 int8-predictor int8 --levels 2 3 4 --bundled w16-v8:int8-predictor \
        --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT8/final/tradeoff" ;;
    compare-v8)  # the app's ONNX path: the five earlier bundled pairs (from git), the sixth, retrieval and the template
      local folders=()
      for c in 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5; do
        models_from_git "$c" "$OUT8/models_$c"
        folders+=(--models "$OUT8/models_$c")
      done
      sketchmesh eval "${folders[@]}" --models "$OUT8/final/models_int8" --data "$DATA2" --views 4 --max-samples 39 \
        --threads 2 --out "$OUT8/final/compare" ;;
    mirror-check-v8)  # how near a mirrored generated input is to what the generator makes of the mirrored sketch (what
      # --mirror approximates), beside the generator's own error against the true image: 96 training views, clean
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      python3 - "$DATA2" "$OUT8/models_fifth/generator.onnx" <<'EOF'
import sys, numpy as np, torch
from engine.models import load_generator
from engine.pipeline import downsample_normals
from training.data.dataset import ShapeViewDataset
from training.data.mirror import mirror_normal_image
ds = ShapeViewDataset(sys.argv[1], "train", extra_views=0, augment_strength=0.0)
gen = load_generator(sys.argv[2], threads=2)
def g64(sketch):
    (n,) = gen.session.run(None, {gen.input_name: np.ascontiguousarray(sketch, np.float32)[None, None]})
    return torch.from_numpy(downsample_normals(np.clip(n, 0.0, 1.0).astype(np.float32), 64)[0])
mirror_err, own_err, flip_only = [], [], []
for i in np.linspace(0, len(ds) - 1, 96).astype(int):
    item = ds[int(i)]
    sketch = np.asarray(item["sketch"])[0]
    a, b = g64(sketch), g64(sketch[:, ::-1])
    mirror_err.append(float((mirror_normal_image(a) - b).abs().mean()))
    flip_only.append(float((a.flip(-1) - b).abs().mean()))
    own_err.append(float((a - torch.as_tensor(np.asarray(item["normals64"]))).abs().mean()))
print("96 clean training views, mean |difference| per pixel and channel at 64x64:")
print(f"  mirrored generated image vs the generator's image of the mirrored sketch: {np.mean(mirror_err):.4f}")
print(f"  the same, flipped without negating x (what a plain image flip would feed): {np.mean(flip_only):.4f}")
print(f"  the generator's image vs the true normal image (its own error):            {np.mean(own_err):.4f}")
EOF
      ;;
    val-v8)  # predictor-v8's two runs against the fifth predictor (imported) on the validation split, clean sketches
      sketchmesh eval "$RUNS8/v8_mirror" --data "$DATA2" --split val --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS8/v8_more" --baseline-run "$RUNS8/fifth/predictor" --no-retrieval \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT8/val_clean" ;;
    eval-v8|eval-strong-v8|eval-side-v8|eval-gt-v8)  # the same on the test split
      eval_case "$1"
      sketchmesh eval "$RUNS8/v8_mirror" --data "$DATA2" --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS8/v8_more" --baseline-run "$RUNS8/fifth/predictor" --no-retrieval "${EVAL_EXTRA[@]}" \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT8/$EVAL_NAME" ;;
    compare-v7)  # the app's ONNX path: the four earlier bundled pairs (from git), the fifth, retrieval and the template
      local folders=()
      for c in 2e5204b cc51aaf 0c5ab8e 3a1ec5a; do
        models_from_git "$c" "$OUT7/models_$c"
        folders+=(--models "$OUT7/models_$c")
      done
      sketchmesh eval "${folders[@]}" --models "$OUT7/models_int8" --data "$DATA2" --views 4 --max-samples 39 --threads 2 \
        --out "$OUT7/compare" ;;
    eval-v6|eval-strong-v6|eval-side-v6|eval-gt-v6)  # the surface measure of voxel IoU (a thin part keeps its
      # cells): the bundled predictor, the third models', the equal-time control and full loss of trials-v5, retrieval
      eval_case "$1"
      sketchmesh eval "$RUNS2/v4_generated_more" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/mesh_silhouette" --baseline-run "$RUNS2/v4_generated_last" --baseline-run "$RUNS2/v5_full" \
        "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 --out "$OUT6/$EVAL_NAME" ;;
    eval-train-v6)  # the same predictors from clean sketches of training views (how well they fit what they trained on)
      sketchmesh eval "$RUNS2/v4_generated_more" --data "$DATA2" --split train --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_generated_last" --no-retrieval --max-samples "$SAMPLES2" --threads 2 \
        --out "$OUT6/eval_train" ;;
    compare-v6)  # compare-v4's app path (the four bundled pairs from git, retrieval, the template sphere), surface measure
      local folders=()
      for c in 2e5204b cc51aaf 0c5ab8e 3a1ec5a; do
        models_from_git "$c" "$OUT6/models_$c"
        folders+=(--models "$OUT6/models_$c")
      done
      sketchmesh eval "${folders[@]}" --data "$DATA2" --views 4 --max-samples 39 --threads 2 --out "$OUT6/compare" ;;
    eval-v4|eval-strong-v4|eval-side-v4|eval-gt-v4)  # the two against their start and the third models' predictor
      eval_case "$1"
      local more=()  # predictor-v4-more's run first where it exists
      [ ! -d "$RUNS2/v4_generated_more" ] || more=("$RUNS2/v4_generated_more" --baseline-run)
      sketchmesh eval "${CENTRES[@]}" "${more[@]}" "$RUNS2/v4_generated_inputs" --data "$DATA2" --generator-run "$RUNS2/normals16" \
        --baseline-run "$RUNS2/v4_true_inputs" --baseline-run "$RUNS2/continued_2d" --baseline-run "$RUNS2/mesh_silhouette" \
        "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 --out "$OUT4/$EVAL_NAME" ;;
    export-v4)  # the chosen predictor (PRED4 [v4_generated_more]) with the third models' generator, int8 predictor
      local pred=${PRED4:-v4_generated_more}
      sketchmesh export "$RUNS2/$pred" --generator-run "$RUNS2/normals16" -o "$OUT4/models_fp32"
      sketchmesh export "$RUNS2/$pred" --generator-run "$RUNS2/normals16" -o "$OUT4/models_int8" --quantize int8 ;;
    tradeoff-v4)  # error against run time in the app's engine: the fourth pair beside the third's and width 8
      sketchmesh bench tradeoff "${CENTRES[@]}" --data "$DATA2" --variant "w16-v4=$OUT4/models_fp32" \
        --variant "w16-v3=$OUT2/models_silhouette" --variant "w8-full=$OUT2/models_w8_pretrained" \
        --precisions fp32 int8-predictor int8 --levels 2 3 4 --bundled w16-v4:int8-predictor \
        --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT4/tradeoff" ;;
    compare-v4)  # the app's ONNX path: the four bundled pairs in turn (from git), retrieval and the template sphere
      local folders=()
      for c in 2e5204b cc51aaf 0c5ab8e; do
        models_from_git "$c" "$OUT4/models_$c"
        folders+=(--models "$OUT4/models_$c")
      done
      sketchmesh eval "${CENTRES[@]}" "${folders[@]}" --models "$OUT4/models_int8" --data "$DATA2" --views 4 --max-samples 39 \
        --threads 2 --out "$OUT4/compare" ;;
    export-v2)  # the fine-tuned pair (float32; int8 predictor), the pre-trained pairs (full loss; silhouette-only,
      # also with an int8 predictor: the bundled pair, see ship-v2) and the width-8 generator's pair
      sketchmesh export "$RUNS2/joint" -o "$OUT2/models_fp32"
      sketchmesh export "$RUNS2/joint" -o "$OUT2/models_int8" --quantize int8
      sketchmesh export "$RUNS2/mesh_full" --generator-run "$RUNS2/normals16" -o "$OUT2/models_pretrained"
      sketchmesh export "$RUNS2/mesh_silhouette" --generator-run "$RUNS2/normals16" -o "$OUT2/models_silhouette"
      sketchmesh export "$RUNS2/mesh_silhouette" --generator-run "$RUNS2/normals16" -o "$OUT2/models_silhouette_int8" \
        --quantize int8
      sketchmesh export "$RUNS2/mesh_full" --generator-run "$RUNS2/normals8" -o "$OUT2/models_w8_pretrained" ;;
    eval-v2|eval-strong-v2|eval-side-v2|eval-gt-v2)  # clean sketches; strong augmentation; 0-degree views only;
      # ground-truth normal images (the mesh step alone). mesh_full and mesh_silhouette read the pre-trained
      # generator's normal images, joint its own.
      eval_case "$1"
      local base=(--baseline-run "$RUNS2/mesh_silhouette")
      [ ! -d "$RUNS2/mesh_n5e-4" ] || base+=(--baseline-run "$RUNS2/mesh_n5e-4")  # the GPU runs' normal weight 0.0005
      [ "$1" = eval-gt-v2 ] || base+=(--baseline-run "$RUNS2/joint")
      [ -z "${PREV_SIL:-}" ] || base+=(--baseline-run "$PREV_SIL")  # all-gpu: the CPU-trained bundled predictor
      sketchmesh eval "${CENTRES[@]}" "$RUNS2/mesh_full" --data "$DATA2" --generator-run "$RUNS2/normals16" "${base[@]}" "${EVAL_EXTRA[@]}" \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT2/$EVAL_NAME" ;;
    gallery-v2)  # the bundled pair on one test shape per category, from 30 degrees and from the side
      sketchmesh gallery --data "$DATA2" --models "$SHIP_MODELS" -o "$SHIP_OUT/gallery.png"
      sketchmesh gallery --data "$DATA2" --models "$SHIP_MODELS" --elevation 0 --azimuth 90 \
        -o "$SHIP_OUT/gallery_side.png" ;;
    tradeoff-v2)  # error against run time: generator width, precision and template level, in the app's engine
      sketchmesh bench tradeoff "${CENTRES[@]}" --data "$DATA2" --variant "w16-silhouette=$OUT2/models_silhouette" \
        --variant "w16-full=$OUT2/models_pretrained" --variant "w16-joint=$OUT2/models_fp32" \
        --variant "w8-full=$OUT2/models_w8_pretrained" \
        --precisions fp32 int8-predictor int8 --levels 2 3 4 --bundled w16-silhouette:int8-predictor \
        --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT2/tradeoff" ;;
    refine-v2)  # the app's outline refinement with the bundled models: IoU against run time per step count N
      sketchmesh bench refine "${CENTRES[@]}" --data "$DATA2" --max-samples "$SAMPLES2" --out "$SHIP_OUT/refine" ;;
    compare-v2)  # the app's ONNX path on the new test split: the first bundled models (from git) against the
      # candidate pairs, with retrieval and the template sphere as floors (`sketchmesh eval --models`)
      models_from_git "2e5204b" "$OUT2/models_v1"
      local prev=()
      if [ -n "${PREV_MODELS:-}" ]; then  # all-gpu: the second bundled models too (issue 16, CPU-trained)
        models_from_git "$PREV_MODELS" "$OUT2/models_v2"
        prev=(--models "$OUT2/models_v2")
      fi
      sketchmesh eval "${CENTRES[@]}" --models "$OUT2/models_v1" "${prev[@]}" --models "$OUT2/models_silhouette_int8" --models "$OUT2/models_int8" \
        --data "$DATA2" --views 4 --max-samples 39 --threads 2 --out "$OUT2/compare" ;;
    ship-v2)  # the chosen pair becomes the app's bundled models: the one that scored best from sketches
      # (clean, strong and side views: the silhouette-only predictor with the pre-trained generator; model card)
      mkdir -p assets/models
      cp "$SHIP_MODELS/"*.onnx assets/models/ ;;
    docs-v2)  # the README's pictures, from the outputs above and the app itself (Xvfb when headless)
      mkdir -p docs
      cp "$SHIP_OUT/gallery.png" docs/gallery.png
      cp "$SHIP_OUT/gallery_side.png" docs/gallery_side.png
      cp "$SHIP_OUT/tradeoff/tradeoff.png" docs/tradeoff.png
      cp "$SHIP_OUT/eval_clean/eval_test.png" docs/eval_test.png
      cp "$SHIP_OUT/refine/refine.png" docs/refine.png
      local shot=(sketchmesh --open assets/samples/chair_chair_00018_v3.png --screenshot docs/app.png)
      if [ -n "${DISPLAY:-}" ]; then "${shot[@]}"; else xvfb-run -a -s "-screen 0 1600x1000x24" "${shot[@]}"; fi ;;
    fetch-gpu)  # what training/gpu_lease.sh brought back from a lent GPU (GPU_FILES: the folder the device tool
      # copied $OUT to) becomes run folders RUNS2/NAME (checkpoint without optimiser state, logs, config).
      # GPU_BASIS (optional): the predictor basis `gpu_lease.sh basis` saved on that machine, for checkpoints
      # written before the basis was stored in them (issue 16's GPU runs; see CompactMeshPredictor.basis)
      # (gpu_predictor.sh sends a checkpoint over 16 MiB as NAME.pt.part-aa, -ab, ...: joined here)
      : "${GPU_FILES:?set GPU_FILES to the folder holding the NAME.pt files and logs.tgz of gpu_lease.sh}"
      mkdir -p "$RUNS2"
      python3 - "$GPU_FILES" "$RUNS2" "${GPU_BASIS:-}" <<'EOF'
import sys, tarfile, numpy as np, torch
from pathlib import Path
src, runs, basis = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
with tarfile.open(src / "logs.tgz") as tar:
    for m in tar.getmembers():
        parts = Path(m.name).parts
        if m.isfile() and len(parts) > 2 and ".." not in parts:
            dest = runs / Path(*parts[2:])  # runs/gpu/NAME/file -> RUNS2/NAME/file
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_bytes(tar.extractfile(m).read())
import io
stems = {f.name.split(".pt.part-")[0] for f in src.glob("*.pt.part-*")}  # a checkpoint over 16 MiB came in parts
for f in sorted([*src.glob("*.pt"), *(src / f"{s}.pt" for s in stems)]):
    parts = sorted(src.glob(f"{f.name}.part-*"))
    blob = b"".join(p.read_bytes() for p in parts) if parts else f.read_bytes()
    state = torch.load(io.BytesIO(blob), map_location="cpu", weights_only=True)
    it = int(state["iteration"])
    pred = state["models"].get("predictor")
    if pred is not None and "basis" not in pred:
        if not basis:
            sys.exit(f"{f.name} predates the stored predictor basis: set GPU_BASIS (gpu_lease.sh basis)")
        pred["basis"] = torch.from_numpy(np.load(basis))
    ck = runs / f.stem / "checkpoints"
    ck.mkdir(parents=True, exist_ok=True)
    torch.save(state, ck / f"ckpt_{it:08d}.pt")
    print(f"{f.stem}: iteration {it} -> {ck}")
EOF
      ;;
    all)
      for s in data-v2 normals-v2 normals8-v2 mesh-v2 silhouette-v2 joint-v2 export-v2 eval-v2 eval-strong-v2 \
               eval-side-v2 eval-gt-v2 tradeoff-v2 gallery-v2 compare-v2 ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    all-gpu)  # the third bundled models: training/gpu_lease.sh on a lent GPU (data, the two generator widths and
      # three predictors, side by side), then fetch-gpu and every later step here, on runs/gpu into out/v3
      RUNS2=runs/gpu; OUT2=out/v3; PREV_MODELS=cc51aaf; SHIP_MODELS=$OUT2/models_silhouette_int8; SHIP_OUT=$OUT2
      if [ -d runs/v2/mesh_silhouette ]; then PREV_SIL=runs/v2/mesh_silhouette; fi
      for s in fetch-gpu joint-v2 export-v2 eval-v2 eval-strong-v2 eval-side-v2 eval-gt-v2 tradeoff-v2 gallery-v2 \
               compare-v2 ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    all-v4)  # the fourth bundled models: the third's runs (RUNS2=runs/gpu, out/v3) with the predictor continued
      # on the generator's images (generated-v4, predictor-v4); ceiling-v2 first makes RUNS2/continued_2d
      RUNS2=runs/gpu; OUT2=out/v3; SHIP_MODELS=$OUT4/models_int8; SHIP_OUT=$OUT4
      [ -d "$RUNS2/continued_2d" ] || step ceiling-v2
      for s in generated-v4 predictor-v4 predictor-v4-more eval-v4 eval-strong-v4 eval-side-v4 eval-gt-v4 export-v4 tradeoff-v4 \
               gallery-v2 compare-v4 ship-v2 refine-v2; do step "$s"; done
      step docs-v2 ;;
    trials-v5)  # the fifth session's trials on the fourth bundled models' runs (all-v4 first where they are
      # missing): a second generated set, and doubled fully connected layers, each against the one-set control
      # at equal time (nothing shipped: neither beat it)
      RUNS2=runs/gpu; OUT2=out/v3
      [ -d "$RUNS2/v4_generated_more" ] || step all-v4
      for s in generated-v5 predictor-v5 logs-v5 eval-v5 eval-strong-v5 eval-side-v5 eval-gt-v5 eval-train-v5; do step "$s"; done ;;
    all-v7)  # the fifth bundled models: interior-v6's predictor trained on, chosen on the validation split, shipped
      RUNS2=runs/gpu; OUT2=out/v3; SHIP_MODELS=$OUT7/models_int8; SHIP_OUT=$OUT7; CENTRES=()
      [ -d "$RUNS2/v6_full_interior" ] || step interior-v6
      for s in predictor-v7 val-v7 eval-v7 eval-strong-v7 eval-side-v7 eval-gt-v7 eval-train-v7 export-v7 tradeoff-v7 \
               gallery-v2 compare-v7 ship-v2 refine-v2; do step "$s"; done
      step docs-v2
      for s in control-v7 logs-v7 eval-control-v7 eval-control-strong-v7 eval-control-side-v7 eval-control-gt-v7; do step "$s"; done ;;
    remeasure-v6)  # the sixth session: every headline figure again with the surface measure of voxel IoU
      RUNS2=runs/gpu; OUT2=out/v3
      [ -d "$RUNS2/v5_full" ] || step trials-v5
      for s in eval-v6 eval-strong-v6 eval-side-v6 eval-gt-v6 eval-train-v6 compare-v6 refine-v6 thin-v6 variety-v6 fit-v6; do
        step "$s"
      done ;;
    deep-v6)  # the sixth session's trial: a deeper encoder at trials-v5's protocol (nothing shipped unless it wins)
      RUNS2=runs/gpu; OUT2=out/v3
      [ -d "$RUNS2/v4_generated_last" ] || step trials-v5
      for s in predictor-v6 logs-v6 eval-deep-v6 eval-deep-strong-v6 eval-deep-side-v6 eval-deep-gt-v6 eval-deep-train-v6; do
        step "$s"
      done ;;
    generated-mirror-v9)  # generated-v8's drawings flipped left to right through the same generator (the exact inputs
      # of mirrored items; data generated --mirror), 14 min
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      sketchmesh data generated "$DATA2" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2 ;;
    predictor-v9)  # two candidates for the seventh predictor at equal wall time, side by side on one thread each,
      # from the sixth (v8_more2) with its loss, Adam 2e-4 cosine over V9_ITERS [15000] (V9_MINUTES [80] at most;
      # resumes): trained on as it is (v9_more) and with half of every batch mirrored, a mirrored item reading the
      # generator's image of its flipped drawing (v9_mirror, --mirror 0.5 --mirror-inputs normals16_mirror)
      [ -f "$RUNS8/v8_more2/config.json" ] || { echo "predictor-v9 starts from $RUNS8/v8_more2: run fresh-v8 and predictor-v8-more first" >&2; exit 1; }
      [ -f "$DATA2/.cache/generated/normals16_mirror/info.json" ] || step generated-mirror-v9
      local v9=(--data "$DATA2" --init-mesh "$RUNS8/v8_more2" --lambda-n 0.002 --lr-mesh 2e-4
        --iters "${V9_ITERS:-15000}" --threads 1 --ckpt-every 250 --val-every 0 --quiet
        --max-minutes "${V9_MINUTES:-80}" --input-normals normals16 --no-normal-edges)
      sketchmesh train mesh "${v9[@]}" --out "$RUNS9/v9_more" &
      sketchmesh train mesh "${v9[@]}" --mirror 0.5 --mirror-inputs normals16_mirror --out "$RUNS9/v9_mirror" &
      wait ;;
    gpucarry-v10)  # what the eighth's GPU stage started from: the seventh predictor, gpucarry/v9_mirror
      gpucarry "$RUNS9/v9_mirror" ;;
    gpucarry-v11)  # what the tenth's GPU stage started from: the ninth predictor, gpucarry/v10_more
      gpucarry "$RUNS10/v10_more" ;;
    fetch-gpu-v10)  # what training/gpu_predictor.sh brought back (GPU_FILES: the folder the device tool copied
      # $OUT to; run it once per call's folder) becomes run folders RUNS10/NAME
      RUNS2=$RUNS10 step fetch-gpu ;;
    predictor-v10)  # two candidates for the eighth predictor at equal CPU wall time, side by side on one thread each,
      # with the seventh's recipe (Adam 2e-4 cosine over V10_ITERS [12000], V10_MINUTES [60] at most; resumes):
      # from the GPU-continued seventh (v10_gpu: RUNS10/g10_b512b, fetch-gpu-v10) and from the seventh as shipped
      # (v10_cpu: RUNS9/v9_mirror), both on the generator's images with exact mirrored inputs
      [ -f "$RUNS10/g10_b512b/config.json" ] || { echo "predictor-v10 starts from $RUNS10/g10_b512b: run training/gpu_predictor.sh on a GPU, then fetch-gpu-v10" >&2; exit 1; }
      [ -f "$RUNS9/v9_mirror/config.json" ] || { echo "predictor-v10 compares against $RUNS9/v9_mirror: run fresh-v9 first" >&2; exit 1; }
      finetune_pair "$RUNS10/g10_b512b" "$RUNS9/v9_mirror" "$RUNS10/v10" "${V10_ITERS:-12000}" "${V10_MINUTES:-60}" ;;
    val-v9)  # predictor-v9's two runs against the sixth predictor on the validation split, clean sketches
      sketchmesh eval "$RUNS9/v9_mirror" --data "$DATA2" --split val --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS9/v9_more" --baseline-run "$RUNS8/v8_more2" --no-retrieval \
        --max-samples "$SAMPLES2" --threads 2 --out "$OUT9/val_clean" ;;
    val-strong-v9|val-side-v9|val-gt-v9)  # the tie on clean validation sketches (0.5202 against 0.5208) broken on
      # the validation split's other cases: strong augmentation, side views, ground-truth normal images
      local c=${1/val-/eval-}; eval_case "$c"
      eval_against val "$OUT9/val_${EVAL_NAME#eval_}" "$RUNS9/v9_mirror" "$RUNS9/v9_more" "$RUNS8/v8_more2" ;;
    eval-v9|eval-strong-v9|eval-side-v9|eval-gt-v9)  # the same on the test split, into OUT9/final
      eval_case "$1"
      eval_against test "$OUT9/final/$EVAL_NAME" "$RUNS9/v9_mirror" "$RUNS9/v9_more" "$RUNS8/v8_more2" ;;
    control-v9)  # the seventh predictor's silhouette-only control: v9_mirror's run (the same start, mirrored items,
      # schedule and 15,000 iterations) with the normal weight 0, alone on two threads (V9C_MINUTES [80] at most; resumes)
      sketchmesh train mesh --data "$DATA2" --init-mesh "$RUNS8/v8_more2" --lambda-n 0 --lr-mesh 2e-4 \
        --iters "${V9_ITERS:-15000}" --threads 2 --ckpt-every 250 --val-every 0 --quiet \
        --max-minutes "${V9C_MINUTES:-80}" --input-normals normals16 --no-normal-edges --mirror 0.5 \
        --mirror-inputs normals16_mirror --out "$RUNS9/v9_silhouette" ;;
    eval-control-v9|eval-control-strong-v9|eval-control-side-v9|eval-control-gt-v9)  # full minus silhouette-only:
      # v9_mirror against control-v9 on the test split
      eval_case "${1/control-/}"
      sketchmesh eval "$RUNS9/v9_mirror" --data "$DATA2" --generator-run "$RUNS8/fifth/generator" \
        --baseline-run "$RUNS9/v9_silhouette" --no-retrieval "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" \
        --threads 2 --out "$OUT9/control_$EVAL_NAME" ;;
    logs-v9)  # the v9 runs' training logs: rate and wall time, the silhouette term and normal error
      log_summary "$RUNS9" v9_more v9_mirror ;;
    export-v9)  # the chosen predictor (PRED9 [v9_mirror]) as float32 (the bundled one: int8 costs it 0.002 for no speed,
      # tradeoff-v9) and int8, beside the generator file
      export_pair "$RUNS9/${PRED9:-v9_mirror}" "$OUT9/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v9)  # error against run time in the app's engine: the seventh pair at each precision and template level
      # (run it alone: it times)
      tradeoff_of "w16-v9" "$OUT9/final" ;;
    compare-v9)  # the app's ONNX path: the six earlier bundled pairs (from git), the seventh, retrieval and the template
      compare_pairs "$OUT9" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f ;;
    val-gpu-v10)  # the GPU stage on the validation split's true normal images: its end (g10_b512b) and the first call's
      # run (g10_b512) against the seventh predictor it started from
      sketchmesh eval "$RUNS10/g10_b512b" --data "$DATA2" --split val --gt-normals --baseline-run "$RUNS9/v9_mirror" \
        --baseline-run "$RUNS10/g10_b512" --no-retrieval --max-samples "$SAMPLES2" --threads 2 --out "$OUT10/val_gt_gpu" ;;
    predictor-v10-more)  # the eighth predictor trained on alone on two threads with the same recipe (V10M_ITERS [11000],
      # V10M_MINUTES [42] at most; resumes), then checked against it on the validation split (val-v10-more)
      train7 "$RUNS10/v10_gpu" "$RUNS10/v10_more" "${V10M_ITERS:-11000}" "${V10M_MINUTES:-42}" 2 ;;
    val-v10-more|val-strong-v10-more|val-side-v10-more|val-gt-v10-more)  # v10_more against v10_gpu, validation split
      local c=${1/val-/eval-}; eval_case "${c%-more}"
      eval_against val "$OUT10/more/val_${EVAL_NAME#eval_}" "$RUNS10/v10_more" "$RUNS10/v10_gpu" ;;
    eval-v10-more|eval-strong-v10-more|eval-side-v10-more|eval-gt-v10-more)  # the same on the test split, into OUT10/more/final
      eval_case "${1%-more}"
      eval_against test "$OUT10/more/final/$EVAL_NAME" "$RUNS10/v10_more" "$RUNS10/v10_gpu" ;;
    export-v10-more)  # v10_more as float32 and int8, beside the generator file
      export_pair "$RUNS10/v10_more" "$OUT10/more/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v10-more)  # error against run time in the app's engine (run it alone: it times)
      tradeoff_of "w16-v10-more" "$OUT10/more/final" ;;
    compare-v10-more)  # the app's ONNX path: the eight bundled pairs so far (from git), v10_more, retrieval, the template
      compare_pairs "$OUT10/more" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f bd55d3c 6e6475c ;;
    val-v10|val-strong-v10|val-side-v10|val-gt-v10)  # predictor-v10's two runs against the seventh, validation split
      local c=${1/val-/eval-}; eval_case "$c"
      eval_against val "$OUT10/val_${EVAL_NAME#eval_}" "$RUNS10/v10_gpu" "$RUNS10/v10_cpu" "$RUNS9/v9_mirror" ;;
    eval-v10|eval-strong-v10|eval-side-v10|eval-gt-v10)  # the same on the test split, into OUT10/final
      eval_case "$1"
      eval_against test "$OUT10/final/$EVAL_NAME" "$RUNS10/v10_gpu" "$RUNS10/v10_cpu" "$RUNS9/v9_mirror" ;;
    logs-v10)  # the v10 runs' training logs: rate and wall time, the silhouette term and normal error
      log_summary "$RUNS10" v10_gpu v10_cpu ;;
    export-v10)  # the chosen predictor (PRED10 [v10_gpu]) as float32 and int8, beside the generator file
      export_pair "$RUNS10/${PRED10:-v10_gpu}" "$OUT10/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v10)  # error against run time in the app's engine: the eighth pair at each precision and template level
      # (run it alone: it times)
      tradeoff_of "w16-v10" "$OUT10/final" ;;
    compare-v10)  # the app's ONNX path: the seven earlier bundled pairs (from git), the eighth, retrieval and the template
      compare_pairs "$OUT10" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f bd55d3c ;;
    fetch-gpu-v11)  # what gpu_predictor.sh brought back for the tenth (GPU_FILES, once per call's folder) -> RUNS11/NAME
      RUNS2=$RUNS11 step fetch-gpu ;;
    predictor-v12-more)  # v12_big trained on alone on two threads with the same recipe (V12M_ITERS [8000], V12M_MINUTES
      # [45] at most; resumes): does the larger predictor close its gap to the ninth from sketches with CPU time?
      PRED_ARCH=$BIG_ARCH train7 "$RUNS12/v12_big" "$RUNS12/v12_more" "${V12M_ITERS:-8000}" "${V12M_MINUTES:-45}" 2 ;;
    val-v12-more|val-strong-v12-more|val-side-v12-more|val-gt-v12-more)  # v12_more against v12_big and the ninth,
      # validation split
      local c=${1/val-/eval-}; eval_case "${c%-more}"
      eval_against val "$OUT12/more/val_${EVAL_NAME#eval_}" "$RUNS12/v12_more" "$RUNS12/v12_big" "$RUNS10/v10_more" ;;
    fit-gt-v12)  # how well the larger predictor fits what it trained on: the training split's true normal images, its GPU
      # stage (big12b) against the ninth's (g11_b512b) and the ninth (fit-gt-v11's measure; compare val-gpu-v12)
      EVAL_EXTRA=(--gt-normals)
      eval_against train "$OUT12/fit_gt_train" "$RUNS12/big12b" "$RUNS11/g11_b512b" "$RUNS10/v10_more" ;;
    cost-v12)  # what the larger predictor costs in the app's engine: every stage's latency, float32 on two threads, for
      # the larger predictor's pair (export-v12) and the bundled pair (run it alone: it times)
      mkdir -p "$OUT12"
      sketchmesh bench engine --models assets/models --threads 2 --variants fp32 --runs 50 --json "$OUT12/engine_bundled.json"
      sketchmesh bench engine --models "$OUT12/final/models_fp32" --threads 2 --variants fp32 --runs 50 \
        --json "$OUT12/engine_v12.json" ;;
    gallery-v12)  # the larger predictor's pair (export-v12) on one test shape per category (gallery-v2 into OUT12/final), to look at beside the ninth's
      SHIP_MODELS=$OUT12/final/models_fp32 SHIP_OUT=$OUT12/final step gallery-v2 ;;
    predictor-v12-more2)  # v12_more trained on once more with the same recipe (V12M2_ITERS [7000], V12M2_MINUTES [35];
      # resumes): v12_more2, checked by val-v12-more2
      PRED_ARCH=$BIG_ARCH train7 "$RUNS12/v12_more" "$RUNS12/v12_more2" "${V12M2_ITERS:-7000}" "${V12M2_MINUTES:-35}" 2 ;;
    val-v12-more2)  # v12_more2 against v12_more and the ninth, validation split, clean sketches
      eval_case eval
      eval_against val "$OUT12/more2/val_clean" "$RUNS12/v12_more2" "$RUNS12/v12_more" "$RUNS10/v10_more" ;;
    gpucarry-v12)  # what the larger predictor's next GPU stage starts from: its newest run (PRED12 [v12_more2]) in
      # gpucarry/NAME, and the fifth pair's model folder in gpucarry/models_fifth (13 MB: `data generated` reads its
      # generator) for gpu_predictor.sh's INPUTS=generated
      gpucarry "$RUNS12/${PRED12:-v12_more2}"
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      mkdir -p gpucarry/models_fifth && cp "$OUT8"/models_fifth/*.onnx gpucarry/models_fifth/ ;;
    fetch-gpu-v12)  # what gpu_predictor.sh brought back for the larger predictor (GPU_FILES, once per call's folder)
      RUNS2=$RUNS12 step fetch-gpu ;;
    val-gpu-v12)  # the larger predictor (RUNS12/big12b, trained from the start on true normal images) on the validation
      # split's true normal images against the ninth's GPU stage (g11_b512b, the best predictor there so far) and its
      # own first call (big12)
      sketchmesh eval "$RUNS12/big12b" --data "$DATA2" --split val --gt-normals --baseline-run "$RUNS11/g11_b512b" \
        --baseline-run "$RUNS12/big12" --no-retrieval --max-samples "$SAMPLES2" --threads 2 --out "$OUT12/val_gt_gpu" ;;
    predictor-v12)  # the larger predictor fine-tuned here on the generator's images with the seventh's recipe, alone on
      # two threads (V12_ITERS [8000], V12_MINUTES [50] at most; resumes): v12_big, against the ninth and v11_cpu (the
      # ninth fine-tuned 10,000 iterations more, predictor-v11)
      [ -f "$RUNS12/big12b/config.json" ] || { echo "predictor-v12 starts from $RUNS12/big12b: run training/gpu_predictor.sh fresh on a GPU, then fetch-gpu-v12" >&2; exit 1; }
      PRED_ARCH=$BIG_ARCH train7 "$RUNS12/big12b" "$RUNS12/v12_big" "${V12_ITERS:-8000}" "${V12_MINUTES:-50}" 2 ;;
    val-v12|val-strong-v12|val-side-v12|val-gt-v12)  # the larger predictor fine-tuned (v12_big) against the ninth and
      # v11_cpu (the ninth fine-tuned 10,000 iterations more), validation split
      local c=${1/val-/eval-}; eval_case "$c"
      eval_against val "$OUT12/val_${EVAL_NAME#eval_}" "$RUNS12/v12_big" "$RUNS10/v10_more" "$RUNS11/v11_cpu" ;;
    eval-v12|eval-strong-v12|eval-side-v12|eval-gt-v12)  # the same on the test split, into OUT12/final
      eval_case "$1"
      eval_against test "$OUT12/final/$EVAL_NAME" "$RUNS12/v12_big" "$RUNS10/v10_more" "$RUNS11/v11_cpu" ;;
    logs-v12)  # the larger predictor's runs: rate and wall time, the silhouette term and normal error
      log_summary "$RUNS12" big12 big12b v12_big v12_more v12_more2 ;;
    export-v12)  # the larger predictor (PRED12 [v12_more]) as float32 and int8, beside the generator file
      export_pair "$RUNS12/${PRED12:-v12_more}" "$OUT12/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v12)  # error against run time in the app's engine (run it alone: it times)
      tradeoff_of "w16-v12" "$OUT12/final" ;;
    compare-v12)  # the app's ONNX path: the nine bundled pairs so far (from git), the larger predictor's (export-v12),
      # retrieval, the template
      compare_pairs "$OUT12" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f bd55d3c 6e6475c 43b2613 ;;
    fresh-v12)  # the larger predictor (after fresh-v11: data-v2, the fifth generator's images; gpu_predictor.sh fresh's
      # two calls in GPU_FILES1 and GPU_FILES2): fetched, checked, fine-tuned, measured
      GPU_FILES=${GPU_FILES1:?set GPU_FILES1 and GPU_FILES2 to the folders of the two calls} step fetch-gpu-v12
      GPU_FILES=${GPU_FILES2:?set GPU_FILES2} step fetch-gpu-v12
      for s in val-gpu-v12 predictor-v12 val-v12 val-strong-v12 val-side-v12 val-gt-v12 eval-v12 eval-strong-v12 \
               eval-side-v12 eval-gt-v12 logs-v12; do step "$s"; done ;;
    all-v12)  # the larger predictor's pair (after fresh-v12): exported, timed, shipped
      SHIP_MODELS=$OUT12/final/models_fp32; SHIP_OUT=$OUT12/final; CENTRES=()
      for s in export-v12 tradeoff-v12 gallery-v2 compare-v12 ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    val-mirror-v13|val-strong-mirror-v13|val-side-mirror-v13|val-gt-mirror-v13)  # mirror averaging (the engine's
      # mirror_average) on the ninth and the larger predictor (v12_more2): plain and +mirror in one table, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT13/val_${EVAL_NAME#eval_}" "$RUNS10/v10_more" "$RUNS12/v12_more2" ;;
    val624-mirror-v13)  # the ninth plain and +mirror on 624 validation sketches, clean (a finer check of val-mirror-v13)
      EVAL_EXTRA=(--mirror-average)
      SAMPLES2=624 eval_against val "$OUT13/val624_clean" "$RUNS10/v10_more" ;;
    eval-mirror-v13|eval-strong-mirror-v13|eval-side-mirror-v13|eval-gt-mirror-v13)  # the ninth plain and +mirror, test
      # split (after the choice on the validation split, OUT13/choice.txt)
      eval_case "$1"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$OUT13/$EVAL_NAME" "$RUNS10/v10_more" ;;
    cost-v13)  # what mirror averaging costs in the app's engine: every stage, bundled pair, float32 plain and +mirror on
      # two threads (run it alone: it times)
      mkdir -p "$OUT13"
      sketchmesh bench engine --models assets/models --threads 2 --variants fp32,fp32+mirror --runs 50 \
        --json "$OUT13/engine_mirror.json" ;;
    compare-v13)  # the bundled pair plain and +mirror in the app's own path (39 test shapes x 4 drawings, compare-v10-more's
      # set), with retrieval and the template sphere
      sketchmesh eval --models assets/models --mirror-average --data "$DATA2" --views 4 --max-samples 39 --threads 2 \
        --out "$OUT13/compare" ;;
    tradeoff-v13)  # error against run time with mirror averaging: the bundled pair at each precision, plain and +mirror,
      # and template level, in the app's engine, fp32+mirror marked as what the app runs (run it alone: it times)
      sketchmesh bench tradeoff --data "$DATA2" --variant "ninth=assets/models" \
        --precisions fp32 fp32+mirror int8-predictor int8-predictor+mirror int8 int8+mirror --levels 2 3 4 \
        --bundled ninth:fp32+mirror --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT13/tradeoff" ;;
    refine-v13)  # the app's outline refinement on top of mirror averaging (refine-v2 with --mirror-average)
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --out "$OUT13/refine" ;;
    gallery-v13)  # the gallery as the app now predicts (gallery-v2 with --mirror-average), into OUT13
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average -o "$OUT13/gallery.png"
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average --elevation 0 --azimuth 90 \
        -o "$OUT13/gallery_side.png" ;;
    docs-v13)  # the README's pictures from OUT13 (docs-v2's, with mirror averaging)
      SHIP_OUT=$OUT13 step docs-v2 ;;
    predictor-v13)  # mirror averaging learned: the ninth trained on side by side on one thread each with the seventh's
      # recipe (Adam 2e-4 cosine over V13_ITERS [6000], V13_MINUTES [30] at most; resumes), plain (v13_ctl) and with the
      # mirror-consistency term at weight V13_MC [50] (v13_mc: each prediction against its mirror counterpart's, mirrored back)
      train7 "$RUNS10/v10_more" "$RUNS13/v13_ctl" "${V13_ITERS:-6000}" "${V13_MINUTES:-30}" 1 &
      TRAIN_EXTRA="--mirror-consistency ${V13_MC:-50}" train7 "$RUNS10/v10_more" "$RUNS13/v13_mc" "${V13_ITERS:-6000}" \
        "${V13_MINUTES:-30}" 1 &
      wait ;;
    val-v13|val-strong-v13|val-side-v13|val-gt-v13)  # v13_mc against v13_ctl and the ninth, plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT13/mc/val_${EVAL_NAME#eval_}" "$RUNS13/v13_mc" "$RUNS13/v13_ctl" "$RUNS10/v10_more" ;;
    predictor-v13-big)  # the larger predictor (v12_more2), whose vertex placement defeats mirror averaging, trained on with
      # the mirror-consistency term (weight V13B_MC [50]) alone on two threads, the seventh's recipe (V13B_ITERS [5000],
      # V13B_MINUTES [30]; resumes); its control is v12_more2's own last round (predictor-v12-more2: +0.001 in 35 min)
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" train7 "$RUNS12/v12_more2" \
        "$RUNS13/v13_big_mc" "${V13B_ITERS:-5000}" "${V13B_MINUTES:-30}" 2 ;;
    val-v13-big|val-strong-v13-big|val-side-v13-big)  # v13_big_mc against v12_more2 and the ninth, plain and +mirror,
      # validation split
      local c=${1%-big}; eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT13/big_mc/val_${EVAL_NAME#eval_}" "$RUNS13/v13_big_mc" "$RUNS12/v12_more2" "$RUNS10/v10_more" ;;
    logs-v13)  # predictor-v13's two runs and predictor-v13-big's: iterations, rates, loss terms
      log_summary "$RUNS13" v13_ctl v13_mc v13_big_mc ;;
    predictor-v14-big)  # v13_big_mc trained on alone on two threads with the same term and recipe (V14B_ITERS [11000],
      # V14B_MINUTES [85] at most; resumes): the larger predictor had gained +0.006 averaged in its first 30 minutes
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" train7 "$RUNS13/v13_big_mc" \
        "$RUNS14/v14_big_mc" "${V14B_ITERS:-11000}" "${V14B_MINUTES:-85}" 2 ;;
    val-v14-big|val-strong-v14-big|val-side-v14-big)  # v14_big_mc against v13_big_mc and the ninth, plain and +mirror,
      # validation split
      local c=${1%-big}; eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT14/big_mc/val_${EVAL_NAME#eval_}" "$RUNS14/v14_big_mc" "$RUNS13/v13_big_mc" "$RUNS10/v10_more" ;;
    logs-v14)  # predictor-v14-big's run: iterations, rates, loss terms
      log_summary "$RUNS14" v14_big_mc ;;
    eval-v14|eval-strong-v14|eval-side-v14|eval-gt-v14)  # v14_big_mc against the ninth, plain and +mirror, test split
      # (after the choice on the validation split, OUT14/big_mc/choice.txt)
      eval_case "$1"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$OUT14/final/$EVAL_NAME" "$RUNS14/v14_big_mc" "$RUNS10/v10_more" ;;
    export-v14)  # v14_big_mc as float32 and int8, beside the generator file
      export_pair "$RUNS14/v14_big_mc" "$OUT14/final" "$OUT8/models_fifth/generator.onnx" ;;
    cost-v14)  # every stage of the app's engine, plain and +mirror, v14's pair (export-v14) against the bundled one before
      # it ships (run it alone: it times)
      mkdir -p "$OUT14"
      sketchmesh bench engine --models "$OUT14/final/models_fp32" --threads 2 --variants fp32,fp32+mirror --runs 50 \
        --json "$OUT14/engine_v14.json" ;;
    tradeoff-v14)  # error against run time: v14's pair at each precision, plain and +mirror, and template level, in the
      # app's engine, fp32+mirror marked as what the app runs (run it alone: it times)
      sketchmesh bench tradeoff --data "$DATA2" --variant "v14=$OUT14/final/models_fp32" \
        --precisions fp32 fp32+mirror int8-predictor int8-predictor+mirror --levels 2 3 4 \
        --bundled v14:fp32+mirror --max-samples "$TRADEOFF_SAMPLES" --threads 2 --out "$OUT14/final/tradeoff" ;;
    compare-v14)  # the app's own path: the ninth (bundled before v14 ships) and v14's pair, both +mirror, 39 test shapes x
      # 4 drawings, with retrieval and the template sphere
      models_from_git fa65062 "$OUT14/models_ninth"
      sketchmesh eval --models "$OUT14/models_ninth" --models "$OUT14/final/models_fp32" --mirror-average --data "$DATA2" \
        --views 4 --max-samples 39 --threads 2 --out "$OUT14/final/compare" ;;
    refine-v14)  # the app's outline refinement on the shipped pair with mirror averaging (after ship-v14)
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --out "$OUT14/final/refine" ;;
    repair-v14)  # the fold repair on the bundled pair as the app runs it (mirror averaging on): bench refine at N = 0
      # and 3 with the repair off and on, one after the other on the same idle machine (run it alone: it times)
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --steps 0 3 \
        --out "$OUT14/final/repair/off"
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --repair-folds --steps 0 3 \
        --out "$OUT14/final/repair/on" ;;
    gallery-repair-v14)  # the gallery as the app predicts now, fold repair on (gallery-v14 without it)
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average --repair-folds \
        -o "$OUT14/final/gallery_repair.png" ;;
    gallery-v14)  # the gallery as the app predicts with the shipped pair (after ship-v14)
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average -o "$OUT14/final/gallery.png"
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average --elevation 0 --azimuth 90 \
        -o "$OUT14/final/gallery_side.png" ;;
    ship-v14)  # v14's pair with the int8 predictor becomes the app's bundled models: the float32 one's voxel IoU in
      # tradeoff-v14, in 18 MB instead of 39 (no file over 20 MiB in the repository)
      SHIP_MODELS=$OUT14/final/models_int8 step ship-v2 ;;
    all-v14)  # after predictor-v14-big and the choice on the validation split: measured, exported, timed, shipped
      SHIP_OUT=$OUT14/final
      for s in eval-v14 eval-strong-v14 eval-side-v14 eval-gt-v14 export-v14 cost-v14 tradeoff-v14 compare-v14 ship-v14 \
               refine-v14 gallery-v14 docs-v2; do step "$s"; done ;;
    eval-v15|eval-strong-v15|eval-side-v15|eval-gt-v15|eval-v17|eval-strong-v17|eval-side-v17|eval-gt-v17|eval-v18|eval-strong-v18|eval-side-v18|eval-gt-v18|eval-v19|eval-strong-v19|eval-side-v19|eval-gt-v19|eval-v20|eval-strong-v20|eval-side-v20|eval-gt-v20|eval-v21|eval-strong-v21|eval-side-v21|eval-gt-v21|eval-v22|eval-strong-v22|eval-side-v22|eval-gt-v22|\
    eval-v23|eval-strong-v23|eval-side-v23|eval-gt-v23|eval-v24|eval-strong-v24|eval-side-v24|eval-gt-v24|\
    eval-v25|eval-strong-v25|eval-side-v25|eval-gt-v25|\
    eval-v26|eval-strong-v26|eval-side-v26|eval-gt-v26|eval-v27|eval-strong-v27|eval-side-v27|eval-gt-v27)  # a shipped
      # candidate (candidate: the eleventh, v15_control, against the tenth; the twelfth, v17_aligned, against the
      # eleventh), plain and +mirror, test split (after the choice on the validation split)
      candidate "$1"; eval_case "$1"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$CAND_OUT/final/$EVAL_NAME" "$CAND_RUN" "$CAND_BASE" ;;
    export-v15|export-v17|export-v18|export-v19|export-v20|export-v21|export-v22|export-v23|export-v24|export-v25|export-v26|export-v27)  # the candidate as float32, int8 and with float16-stored weights (what ships), beside the
      # generator file
      candidate "$1"
      export_pair "$CAND_RUN" "$CAND_OUT/final" "$OUT8/models_fifth/generator.onnx"
      rm -rf "$CAND_OUT/final/models_fp16"
      sketchmesh export "$CAND_RUN" -o "$CAND_OUT/final/models_fp16" --quantize fp16
      cp "$OUT8/models_fifth/generator.onnx" "$CAND_OUT/final/models_fp16/" ;;
    cost-v15|cost-v17|cost-v18|cost-v19|cost-v20|cost-v21|cost-v22|cost-v23|cost-v24|cost-v25|cost-v26|cost-v27)  # every stage of the app's engine, plain and +mirror, the candidate as shipped (float16-stored
      # predictor weights; the variant "fp32" is the models as given) (run it alone: it times)
      candidate "$1"; mkdir -p "$CAND_OUT"
      sketchmesh bench engine --models "$CAND_OUT/final/models_fp16" --threads 2 --variants fp32,fp32+mirror --runs 50 \
        --json "$CAND_OUT/engine_$CAND_NAME.json" ;;
    tradeoff-v15|tradeoff-v17|tradeoff-v18|tradeoff-v19|tradeoff-v20|tradeoff-v21|tradeoff-v22|tradeoff-v23|tradeoff-v24|tradeoff-v25|tradeoff-v26|tradeoff-v27)  # error against run time: the candidate at each precision, plain and +mirror, and template
      # level; NAME-fp16w, the predictor's weights stored in float16 ("fp32": the files as given), +mirror at level 3
      # marked as what the app runs (run it alone: it times)
      candidate "$1"
      sketchmesh bench tradeoff --data "$DATA2" --variant "$CAND_NAME=$CAND_OUT/final/models_fp32" \
        --variant "$CAND_NAME-fp16w=$CAND_OUT/final/models_fp16" \
        --precisions fp32 fp32+mirror int8-predictor int8-predictor+mirror --levels 2 3 4 \
        --bundled "$CAND_NAME-fp16w:fp32+mirror" --max-samples "$TRADEOFF_SAMPLES" --threads 2 \
        --out "$CAND_OUT/final/tradeoff" ;;
    compare-v15|compare-v17|compare-v18|compare-v19|compare-v20|compare-v21|compare-v22|compare-v23|compare-v24|compare-v25|compare-v26|compare-v27)  # the app's own path: the pair bundled before (from git) and the candidate as shipped
      # (float16-stored predictor weights), both +mirror, 39 test shapes x 4 drawings, with retrieval and the template sphere
      candidate "$1"
      models_from_git "$CAND_PREV" "$CAND_OUT/models_$CAND_PREV_NAME"
      sketchmesh eval --models "$CAND_OUT/models_$CAND_PREV_NAME" --models "$CAND_OUT/final/models_fp16" --mirror-average \
        --data "$DATA2" --retrieval-data "${CAND_RETRIEVAL:-$DATA2}" --views 4 --max-samples 39 --threads 2 \
        --out "$CAND_OUT/final/compare" ;;
    ship-v15|ship-v17|ship-v18|ship-v19|ship-v20|ship-v21|ship-v22|ship-v23|ship-v24|ship-v25|ship-v26|ship-v27)  # the candidate with its predictor's weights stored in float16 becomes the app's bundled models:
      # the float32 export's accuracy and speed in half its file (no file over 20 MiB in the repository)
      candidate "$1"; SHIP_MODELS=$CAND_OUT/final/models_fp16 step ship-v2 ;;
    refine-v15|refine-v17|refine-v18|refine-v19|refine-v20|refine-v21|refine-v22|refine-v23|refine-v24|refine-v25|refine-v26|refine-v27)  # the app's outline refinement on the shipped pair with mirror averaging (after ship-*)
      candidate "$1"
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --out "$CAND_OUT/final/refine" ;;
    repair-v15|repair-v17|repair-v18|repair-v19|repair-v20|repair-v21|repair-v22|repair-v23|repair-v24|repair-v25|repair-v26|repair-v27)  # the fold repair on the shipped pair (after ship-*), mirror averaged: bench refine at N = 0
      # and 3 with the repair off and on, one after the other on the same idle machine (run it alone: it times)
      candidate "$1"
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --steps 0 3 \
        --out "$CAND_OUT/final/repair/off"
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --repair-folds --steps 0 3 \
        --out "$CAND_OUT/final/repair/on" ;;
    gallery-v15|gallery-v17|gallery-v18|gallery-v19|gallery-v20|gallery-v21|gallery-v22|gallery-v23|gallery-v24|gallery-v25|gallery-v26|gallery-v27)  # the gallery as the app shows it with the shipped pair (after ship-*), from the side, and
      # as it exports (folds repaired)
      candidate "$1"
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average -o "$CAND_OUT/final/gallery.png"
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average --elevation 0 --azimuth 90 \
        -o "$CAND_OUT/final/gallery_side.png"
      sketchmesh gallery --data "$DATA2" --models assets/models --mirror-average --repair-folds \
        -o "$CAND_OUT/final/gallery_repair.png" ;;
    all-v15|all-v17|all-v18|all-v19|all-v20|all-v21|all-v22|all-v23|all-v24|all-v25|all-v26|all-v27)  # after the candidate's training and the choice on the validation split: measured, exported, timed,
      # shipped
      candidate "$1"; SHIP_OUT=$CAND_OUT/final
      local v=${1##*-}
      for s in eval eval-strong eval-side eval-gt export cost tradeoff compare ship refine repair gallery; do
        step "$s-$v"
      done
      step docs-v2 ;;
    control-v15)  # the eleventh predictor's silhouette-only control: predictor-v15-control's run (the same start,
      # v14_big_mc, recipe, mirror-consistency term, schedule and 3,500 iterations) with the normal weight 0, alone on two
      # threads (V15_MINUTES [25] at most; resumes)
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" train7 \
        "$RUNS14/v14_big_mc" "$RUNS14/v15_silhouette" "${V15_ITERS:-3500}" "${V15_MINUTES:-25}" 2 0 ;;
    eval-control-v15|eval-control-strong-v15|eval-control-side-v15)  # full minus silhouette-only for the eleventh pair
      # over its last 3,500 iterations: v15_control against control-v15, plain and +mirror, test split
      local c=${1/control-/}; eval_case "$c"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$OUT15/control/$EVAL_NAME" "$RUNS14/v15_control" "$RUNS14/v15_silhouette" ;;
    gpucarry-v15)  # the slim copy of runs/v14/v15_control a GPU stage starts from (training/gpu_predictor.sh with
      # INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024" EXTRA="--mirror-consistency 50")
      gpucarry "$RUNS14/v15_control" ;;
    predictor-v15-fold)  # the tenth's folds: v14_big_mc trained on with the dihedral smoothness weight at V15_M [0.05]
      # (5x the paper's 0.01), the same recipe and term otherwise, alone on two threads (V15_ITERS [3500], V15_MINUTES [25])
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50} --lambda-m ${V15_M:-0.05}" train7 \
        "$RUNS14/v14_big_mc" "$RUNS14/v15_fold" "${V15_ITERS:-3500}" "${V15_MINUTES:-25}" 2 ;;
    val-v15-fold|val-strong-v15-fold|val-side-v15-fold)  # v15_fold against the tenth (v14_big_mc), plain and +mirror
      local c=${1%-fold}; eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT14/fold/val_${EVAL_NAME#eval_}" "$RUNS14/v15_fold" "$RUNS14/v14_big_mc" ;;
    folds-v15)  # v15_fold's folds: exported (into OUT14/fold) and its unrefined meshes' self-intersections counted by bench
      # refine at N = 0 on the clean test sketches, mirror averaged (the tenth's: refine-v14's N = 0 row); a surface-quality
      # diagnostic, not a choice of accuracy
      export_pair "$RUNS14/v15_fold" "$OUT14/fold" "$OUT8/models_fifth/generator.onnx"
      sketchmesh bench refine --data "$DATA2" --models "$OUT14/fold/models_fp32" --max-samples "$SAMPLES2" --mirror-average \
        --steps 0 --styles clean --out "$OUT14/fold/refine" ;;
    predictor-v15-control)  # v15_fold's control at equal cost: v14_big_mc trained on by the same schedule (V15_ITERS,
      # V15_MINUTES, two threads) with the paper's dihedral weight, so what the 5x weight does is not confused with more training
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" train7 \
        "$RUNS14/v14_big_mc" "$RUNS14/v15_control" "${V15_ITERS:-3500}" "${V15_MINUTES:-25}" 2 ;;
    predictor-v16-smooth)  # the eleventh (v15_control) re-smoothed to damping V16_SMOOTH and trained on (one thread)
      PRED_ARCH="$BIG_ARCH --predictor-smoothing ${V16_SMOOTH:-4}" TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS14/v15_control" "$RUNS16/v16_smooth" "${V16_ITERS:-3000}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16-control)  # its control at equal cost: the eleventh trained on unchanged by the same schedule (one thread)
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS14/v15_control" "$RUNS16/v16_control" "${V16_ITERS:-3000}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16)  # both side by side on the two cores
      step predictor-v16-smooth & step predictor-v16-control & wait ;;
    predictor-v16-damp64)  # the other way: re-smoothed to damping 64 (the rough modes' steps a quarter as long), one thread
      PRED_ARCH="$BIG_ARCH --predictor-smoothing 64" TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS14/v15_control" "$RUNS16/v16_damp64" "${V16_ITERS:-3000}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16-lowlr)  # the control's recipe at a quarter of the peak rate (5e-5): is 2e-4 too high to fine-tune?
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" TRAIN_LR=5e-5 \
        train7 "$RUNS14/v15_control" "$RUNS16/v16_lowlr" "${V16_ITERS:-3000}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16b)  # both side by side on the two cores (after predictor-v16: v16_control is their control too)
      step predictor-v16-damp64 & step predictor-v16-lowlr & wait ;;
    predictor-v16-aligned)  # v16_control with the aligned branch (width V16_ALIGNED [128]) added as the same function,
      # trained on by the control's recipe, one thread: a step costs 1.8x the control's (0.76 against 1.37 it/s side by
      # side), so V16A_ITERS [1100] iterations take the control's time for its 2,000 (equal wall-clock, each its own cosine)
      PRED_ARCH="$BIG_ARCH --predictor-aligned ${V16_ALIGNED:-128}" TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS16/v16_control" "$RUNS16/v16_aligned" "${V16A_ITERS:-1100}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16-control2)  # its control at equal time: v16_control trained on unchanged by the same recipe (V16C_ITERS
      # [2000] iterations)
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS16/v16_control" "$RUNS16/v16_control2" "${V16C_ITERS:-2000}" "${V16_MINUTES:-70}" 1 ;;
    predictor-v16c)  # both side by side on the two cores
      step predictor-v16-aligned & step predictor-v16-control2 & wait ;;
    val-v16c|val-strong-v16c|val-side-v16c)  # the aligned branch against its control, plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT16/valc_${EVAL_NAME#eval_}" "$RUNS16/v16_aligned" "$RUNS16/v16_control2" ;;
    predictor-v17)  # the long run: v16_aligned (the aligned branch, the one trial that was not level) trained on by the
      # same recipe along one cosine of V17_ITERS [6500] iterations on two threads (about 85 minutes alone; its first
      # 1,000 iterations ran along an 8,000-iteration cosine, at most 2% more rate), V17_MINUTES [600] at most per sitting;
      # resumes where a sitting stopped
      PRED_ARCH="$BIG_ARCH --predictor-aligned ${V16_ALIGNED:-128}" TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS16/v16_aligned" "$RUNS16/v17_aligned" "${V17_ITERS:-6500}" "${V17_MINUTES:-600}" 2 ;;
    predictor-v17-control)  # the twelfth's equal-cost control: v16_control2 (the aligned trial's control, no branch)
      # trained on by the same recipe for V17C_ITERS [11700] iterations, 1.8x predictor-v17's 6,500 (the step-cost
      # ratio measured in predictor-v16c), two threads, V17_MINUTES [600] at most per sitting; resumes. Its start was
      # never in git: it runs only where predictor-v16c's runs are
      [ -f "$RUNS16/v16_control2/config.json" ] || { echo "predictor-v17-control starts from $RUNS16/v16_control2 (predictor-v16c), which this machine lacks" >&2; exit 1; }
      PRED_ARCH=$BIG_ARCH TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        train7 "$RUNS16/v16_control2" "$RUNS16/v17_control" "${V17C_ITERS:-11700}" "${V17_MINUTES:-600}" 2 ;;
    models-twelfth-v18)  # the twelfth bundled pair as shipped (git TWELFTH [daf5cee]) into OUT18/models_twelfth
      models_from_git "${TWELFTH:-daf5cee}" "$OUT18/models_twelfth" ;;
    import-v18)  # its predictor back as a training run (RUNS18/twelfth/predictor): weights from the ONNX file (float16-
      # stored), batch norms calibrated on 256 of its generated training inputs, parity checked
      [ -f "$OUT18/models_twelfth/mesh_predictor.onnx" ] || step models-twelfth-v18
      [ -f "$RUNS18/twelfth/predictor/config.json" ] || \
        sketchmesh import-models "$OUT18/models_twelfth" --out "$RUNS18/twelfth" --only predictor --data "$DATA2" --threads 2 ;;
    predictor-v18)  # the twelfth trained on by its recipe (train7 with the aligned branch and the mirror-consistency
      # term) along a new cosine of V18_ITERS [5000] iterations from a peak rate V18_LR [1e-4] (half the twelfth's: it
      # starts trained), two threads, V18_MINUTES [600] at most per sitting; resumes
      PRED_ARCH="$BIG_ARCH --predictor-aligned ${V16_ALIGNED:-128}" TRAIN_EXTRA="--mirror-consistency ${V13B_MC:-50}" \
        TRAIN_LR=${V18_LR:-1e-4} train7 "$RUNS18/twelfth/predictor" "$RUNS18/v18_more" "${V18_ITERS:-5000}" \
        "${V18_MINUTES:-600}" 2 ;;
    val-v18|val-strong-v18|val-side-v18)  # v18_more against its start, the twelfth as imported, plain and +mirror,
      # validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT18/val_${EVAL_NAME#eval_}" "$RUNS18/v18_more" "$RUNS18/twelfth/predictor" ;;
    logs-v18)  # predictor-v18's training log
      log_summary "$RUNS18" v18_more ;;
    fresh-v18)  # the thirteenth candidate from a fresh clone: data, the generator's images, the twelfth imported,
      # trained on, set against it on the validation split
      [ -f "$DATA2/manifest.json" ] || step data-v2
      [ -f "$DATA2/.cache/generated/normals16/info.json" ] || step generated-v8
      [ -f "$DATA2/.cache/generated/normals16_mirror/info.json" ] || step generated-mirror-v9
      for s in import-v8 import-v18 predictor-v18 val-v18 val-strong-v18 val-side-v18 logs-v18; do step "$s"; done ;;
    fit-legs-v19)  # fit-v6 from the legged template (engine.icosphere.template_mesh "legs": the sphere with four legs
      # pulled down from its lower half): does a template with legs lift the direct fit of chairs and tables?
      mkdir -p "$OUT19"
      sketchmesh bench fit --procedural 1 --template legs --smoothing 16 --json "$OUT19/fit_legs.json" ;;
    gpucarry-v19)  # what the fourteenth candidate's GPU stage starts from: the thirteenth predictor as trained
      # (RUNS18/v18_more, fresh-v18) in gpucarry/v18_more;
      # then, on the lent GPU, the two calls in training/gpu_predictor.sh's header (carry .whl and gpucarry/v18_more;
      # GEN_MODELS=assets/models, the same generator file), then fetch-gpu-v19
      [ -f "$RUNS18/v18_more/config.json" ] || { echo "gpucarry-v19 starts from $RUNS18/v18_more: run fresh-v18 first" >&2; exit 1; }
      gpucarry "$RUNS18/v18_more" ;;
    fetch-gpu-v19)  # what gpu_predictor.sh brought back for the fourteenth (GPU_FILES) -> RUNS19/NAME
      RUNS2=$RUNS19 step fetch-gpu ;;
    fetch-gpu-v22)  # what gpu_predictor.sh brought back for the seventeenth candidate (GPU_FILES) -> RUNS22/NAME
      RUNS2=$RUNS22 step fetch-gpu ;;
    fetch-gpu-v25)  # what gpu_predictor.sh brought back from the views-per-shape stage (GPU_FILES) -> RUNS25/NAME
      RUNS2=$RUNS25 step fetch-gpu ;;
    val-v25-gpu|val-strong-v25-gpu|val-side-v25-gpu)  # that stage's run (V25_RUN [g25b]: run on the lent H100 of
      # 2026-11-27 as two calls from the bundled twentieth, g25 then g25b from it, 1,079 iterations at batch 512) and its
      # first call's end (RUNS25/g25) against its start, the twentieth (RUNS24/v24_more), plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT25/val_gpu_${EVAL_NAME#eval_}" "$RUNS25/${V25_RUN:-g25b}" "$RUNS24/v24_more" "$RUNS25/g25" ;;
    views-v22)  # is the predictor specific to the 48 views it was trained at (12 azimuths, 30 degrees apart, at 0 / 15 / 30
      # / 45 degrees)? DATA2's first 20 shapes per category (the same shapes and splits) at 24 of those views
      # (DATAV22 [data/views22]/grid: 12 azimuths at 15 and 30) and at 16 views off them (DATAV22/off: 8 azimuths 45
      # degrees apart at 20 and 40), the sixteenth (RUNS20/v20_more), the GPU stage (RUNS22/g22, trained at 8 x
      # {0, 20, 40}) and the seventeenth (RUNS20/v21_more) on the validation shapes of each; about 10 min of rendering
      # on 2 cores (once: a rerun finds the views rendered)
      local v
      for v in "grid 12 15 30" "off 8 20 40"; do
        read -r name n e1 e2 <<< "$v"
        sketchmesh data --source procedural --shapes-per-category 20 --views "$n" --elevations "$e1" "$e2" --workers 2 \
          --no-progress --out "$DATAV22/$name"
        sketchmesh eval "$RUNS20/v20_more" --data "$DATAV22/$name" --split val \
          --generator-run "$RUNS8/fifth/generator" --baseline-run "$RUNS22/g22" --baseline-run "$RUNS20/v21_more" --no-retrieval \
          --max-samples "$SAMPLES2" --threads 2 --out "$OUT22/views_$name"
      done ;;
    val-v22-gpu|val-strong-v22-gpu|val-side-v22-gpu)  # the GPU stage (RUNS22/g22) against its start, the sixteenth
      # (RUNS20/v20_more), plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT22/val_gpu_${EVAL_NAME#eval_}" "$RUNS22/g22" "$RUNS20/v20_more" ;;
    predictor-v19)  # the GPU stage trained on here side by side at equal wall time, one thread each, by the thirteenth's
      # recipe (train7, aligned branch, mirror-consistency term): at its batch of 32 from peak 1e-4 (v19_b32,
      # V19_B32_ITERS [1900]) and at batch 128 from peak 2e-4 (v19_b128, V19_B128_ITERS [430]): is the CPU recipe's
      # plateau its gradient noise? V19_MINUTES [42] at most each; resumes
      [ -f "$RUNS19/g19/config.json" ] || { echo "predictor-v19 starts from $RUNS19/g19: run the GPU stage and fetch-gpu-v19 first" >&2; exit 1; }
      PRED_ARCH="$BIG_ARCH --predictor-aligned 128" TRAIN_EXTRA="--mirror-consistency 50" TRAIN_LR=1e-4 \
        train7 "$RUNS19/g19" "$RUNS19/v19_b32" "${V19_B32_ITERS:-1900}" "${V19_MINUTES:-42}" 1 &
      PRED_ARCH="$BIG_ARCH --predictor-aligned 128" TRAIN_EXTRA="--mirror-consistency 50 --batch 128" TRAIN_LR=2e-4 \
        train7 "$RUNS19/g19" "$RUNS19/v19_b128" "${V19_B128_ITERS:-430}" "${V19_MINUTES:-42}" 1 &
      wait ;;
    val-v19b|val-strong-v19b|val-side-v19b)  # predictor-v19's two runs against their start g19, +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT19/valb_${EVAL_NAME#eval_}" "$RUNS19/v19_b32" "$RUNS19/v19_b128" "$RUNS19/g19" ;;
    val-v19|val-strong-v19|val-side-v19)  # the GPU stage (RUNS19/g19) against its start, the thirteenth (RUNS18/v18_more),
      # plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT19/val_${EVAL_NAME#eval_}" "$RUNS19/g19" "$RUNS18/v18_more" ;;
    logs-v19)  # the GPU stage's training log beside the thirteenth's, and predictor-v19's runs (when they have run)
      log_summary "$RUNS19" g19 v19_b32 v19_b128; log_summary "$RUNS18" v18_more ;;
    overfit-v20)  # does the fourteenth predictor (RUNS19/g19) generalise or fit worse? Its score on the train split's
      # shapes beside the validation split's (val-v19b), plain, the same measure and sample count
      eval_against train "$OUT20/overfit" "$RUNS19/g19" ;;
    overfit-v21)  # the same for the fifteenth and sixteenth predictors (RUNS20/v20_data, v20_more): did 5,000 more iterations on
      # DATA20 widen the gap between training shapes (DATA2's train split, all of them in DATA20's) and validation shapes
      # (val-*-v20-more)?
      eval_against train "$OUT21/overfit" "$RUNS20/v20_more" "$RUNS20/v20_data" ;;
    data-v20)  # DATA2's 1,300 shapes and 1,300 more (200 per category, the same views): a shape is a function of its
      # (category, index) and its split a hash of them, so DATA2's shape files are linked in, not rendered again,
      # and DATA2's validation and test shapes stay out of training; 21 min on 2 cores
      if [ ! -d "$DATA20/shapes" ] && [ -d "$DATA2/shapes" ]; then mkdir -p "$DATA20" && cp -al "$DATA2/shapes" "$DATA20/"; fi
      sketchmesh data --source procedural --shapes-per-category 200 --views 12 --elevations 0 15 30 45 \
        --workers 2 --out "$DATA20" ;;
    data-v23|data-v24)  # a grown dataset, as data-v20 grew DATA2: DATA20's 2,600 shapes and 1,300 more (DATA30, 300 per
      # category), then DATA30's 3,900 and 1,300 more (DATA40, 400 per category), the same views; the smaller one's shape
      # files linked in, DATA2's validation and test shapes still out of training; about 45 min each on 2 cores
      local from=$DATA20 to=$DATA30 n=300; [ "$1" = data-v24 ] && from=$DATA30 to=$DATA40 n=400
      if [ ! -d "$to/shapes" ] && [ -d "$from/shapes" ]; then mkdir -p "$to" && cp -al "$from/shapes" "$to/"; fi
      sketchmesh data --source procedural --shapes-per-category "$n" --views 12 --elevations 0 15 30 45 \
        --workers 2 --out "$to" ;;
    generated-v23|generated-mirror-v23|generated-v24|generated-mirror-v24)  # generated-v8 and generated-mirror-v9 on the
      # grown dataset's train split (the same generator, settings and names: DATA30's for v23, DATA40's for v24), the rows
      # of the shapes the smaller one holds in the same files copied from its sets (data generated --reuse: its draws of
      # the augmentation; seconds), the about 1,040 new shapes generated: about 15 min each on 2 cores; resume
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      local from=$DATA20 to=$DATA30; [ "${1##*-}" = v24 ] && from=$DATA30 to=$DATA40
      local name=(--name normals16); [ "${1#generated-mirror-}" != "$1" ] && name=(--name normals16_mirror --mirror)
      sketchmesh data generated "$to" --models "$OUT8/models_fifth" "${name[@]}" --workers 2 --reuse "$from" ;;
    predictor-v23)  # the seventeenth predictor (RUNS20/v21_more) trained on DATA30 by the DATA20 recipe (recipe20 on the
      # larger data) into RUNS23/v23_data: V23_ITERS [5000], V23_MINUTES [60] at most, two threads; resumes.
      # predictor-v22-more is its equal-sample control on DATA20 (the same start, recipe and iterations)
      [ -f "$RUNS20/v21_more/config.json" ] || { echo "predictor-v23 starts from $RUNS20/v21_more: run predictor-v21-more first" >&2; exit 1; }
      [ -f "$DATA30/.cache/generated/normals16_mirror/info.json" ] || { echo "predictor-v23 reads $DATA30: run data-v23 generated-v23 generated-mirror-v23 first" >&2; exit 1; }
      DATA20=$DATA30 recipe20 "$RUNS20/v21_more" "$RUNS23/v23_data" "${V23_ITERS:-5000}" "${V23_MINUTES:-60}" 2 ;;
    val-v23|val-strong-v23|val-side-v23)  # predictor-v23's run against its start (RUNS20/v21_more) and, when it has run,
      # its equal-sample control on DATA20 (RUNS20/v22_more), plain and +mirror, on DATA2's validation split
      local bases=("$RUNS20/v21_more"); [ -f "$RUNS20/v22_more/config.json" ] && bases+=("$RUNS20/v22_more")
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT23/val_${EVAL_NAME#eval_}" "$RUNS23/v23_data" "${bases[@]}" ;;
    predictor-v24)  # the eighteenth predictor (RUNS23/v23_data) trained on DATA40 by the same recipe into RUNS24/v24_data:
      # V24_ITERS [4000: the nineteenth's 4,000 in 49.4 min], V24_MINUTES [50] at most, two threads; resumes
      [ -f "$RUNS23/v23_data/config.json" ] || { echo "predictor-v24 starts from $RUNS23/v23_data: run predictor-v23 first" >&2; exit 1; }
      [ -f "$DATA40/.cache/generated/normals16_mirror/info.json" ] || { echo "predictor-v24 reads $DATA40: run data-v24 generated-v24 generated-mirror-v24 first" >&2; exit 1; }
      DATA20=$DATA40 recipe20 "$RUNS23/v23_data" "$RUNS24/v24_data" "${V24_ITERS:-4000}" "${V24_MINUTES:-50}" 2 ;;
    predictor-v24-more|predictor-v25-more)  # another pass along a new cosine on DATA40 by the same recipe: the nineteenth
      # (RUNS24/v24_data, whose 4,000 iterations saw 0.6 of DATA40's 200,784 views) into RUNS24/v24_more, and that, the
      # twentieth, a third time into RUNS24/v25_more; V2X_MORE_ITERS [4000], V2X_MORE_MINUTES [50] at most, two threads;
      # resumes. Set against its start by val-*-v2X-more
      local n=${1#predictor-v}; n=${n%-more}; pass40 "$n"
      local iters=V${n}_MORE_ITERS minutes=V${n}_MORE_MINUTES
      [ -f "$RUNS24/$PASS_FROM/config.json" ] || { echo "$1 starts from $RUNS24/$PASS_FROM: train it first" >&2; exit 1; }
      [ -f "$DATA40/.cache/generated/normals16_mirror/info.json" ] || { echo "$1 reads $DATA40: run data-v24 generated-v24 generated-mirror-v24 first" >&2; exit 1; }
      DATA20=$DATA40 recipe20 "$RUNS24/$PASS_FROM" "$RUNS24/$PASS_TO" "${!iters:-4000}" "${!minutes:-50}" 2 ;;
    average-v25)  # the two cycle ends predictor-v24 and predictor-v24-more averaged weight by weight (sketchmesh average,
      # equal weights, batch norms set from 1,024 of DATA40's generated training inputs) into RUNS24/v25_swa
      [ -f "$RUNS24/v24_more/config.json" ] || { echo "average-v25 needs $RUNS24/v24_more: run predictor-v24-more first" >&2; exit 1; }
      [ -f "$RUNS24/v25_swa/config.json" ] || \
        sketchmesh average "$RUNS24/v24_data" "$RUNS24/v24_more" --out "$RUNS24/v25_swa" --bn-samples 1024 --threads 2 ;;
    val-v24-more|val-strong-v24-more|val-side-v24-more|val-v25-more|val-strong-v25-more|val-side-v25-more)  # a
      # predictor-v2X-more run against its start, plain and +mirror, on DATA2's validation split: the second pass against
      # the nineteenth, with their weight average (RUNS24/v25_swa, average-v25) when it is there (OUT25/val_more_*); the
      # third against the twentieth (OUT25/val_third_*)
      local c=${1%-more} n=${1##*-v}; n=${n%-more}; pass40 "$n"
      local runs=("$RUNS24/$PASS_TO" "$RUNS24/$PASS_FROM") out=$OUT25/val_more
      if [ "$n" = 24 ]; then [ -f "$RUNS24/v25_swa/config.json" ] && runs+=("$RUNS24/v25_swa"); else out=$OUT25/val_third; fi
      eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "${out}_${EVAL_NAME#eval_}" "${runs[@]}" ;;
    val-v24|val-strong-v24|val-side-v24)  # predictor-v24's run against its start, the bundled eighteenth (RUNS23/v23_data),
      # plain and +mirror, on DATA2's validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT24/val_${EVAL_NAME#eval_}" "$RUNS24/v24_data" "$RUNS23/v23_data" ;;
    generated-v20)  # generated-v8 on DATA20's train split (the same generator), 28 min
      DATA2=$DATA20 step generated-v8 ;;
    generated-mirror-v20)  # generated-mirror-v9 on DATA20's train split, 28 min
      DATA2=$DATA20 step generated-mirror-v9 ;;
    predictor-v20)  # the fourteenth predictor (RUNS19/g19) trained on DATA20 by predictor-v19's batch-32 recipe (train7,
      # aligned branch, mirror-consistency term, peak 1e-4 over V20_ITERS [1900]): v19_b32 saw the same samples of DATA2
      # from the same start, so the two differ in their shapes only; V20_MINUTES [45] at most, V20_THREADS [2]; resumes
      [ -f "$RUNS19/g19/config.json" ] || { echo "predictor-v20 starts from $RUNS19/g19: run the GPU stage and fetch-gpu-v19 first" >&2; exit 1; }
      [ -f "$DATA20/.cache/generated/normals16_mirror/info.json" ] || { echo "predictor-v20 reads $DATA20: run data-v20 generated-v20 generated-mirror-v20 first" >&2; exit 1; }
      recipe20 "$RUNS19/g19" "$RUNS20/v20_data" "${V20_ITERS:-1900}" "${V20_MINUTES:-45}" "${V20_THREADS:-2}" ;;
    predictor-v20-more|predictor-v21-more|predictor-v22-more)  # the fifteenth predictor (RUNS20/v20_data) trained on
      # along a new cosine on DATA20 by the same recipe into RUNS20/v20_more (the sixteenth), the sixteenth so again into
      # RUNS20/v21_more (the seventeenth), and the seventeenth into RUNS20/v22_more (5,000 iterations [V2X_MORE_ITERS],
      # 60 minutes at most [V2X_MORE_MINUTES], two threads; resumes): do more passes over the 2,087 shapes keep helping?
      # Set against their start by val-*-v2X-more
      local n=${1#predictor-v}; n=${n%-more}; more_pass "$n"
      local iters=V${n}_MORE_ITERS minutes=V${n}_MORE_MINUTES
      [ -f "$RUNS20/$MORE_FROM/config.json" ] || { echo "$1 starts from $RUNS20/$MORE_FROM: train it first" >&2; exit 1; }
      recipe20 "$RUNS20/$MORE_FROM" "$RUNS20/$MORE_TO" "${!iters:-5000}" "${!minutes:-60}" 2 ;;
    val-v20-more|val-strong-v20-more|val-side-v20-more|val-v21-more|val-strong-v21-more|val-side-v21-more|\
    val-v22-more|val-strong-v22-more|val-side-v22-more)  # a predictor-v2X-more run against its start, +mirror,
      # validation split
      local c=${1%-more} n=${1##*-v}; n=${n%-more}; more_pass "$n"
      local out=OUT$n
      eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "${!out}/val_more_${EVAL_NAME#eval_}" "$RUNS20/$MORE_TO" "$RUNS20/$MORE_FROM" ;;
    val-v20|val-strong-v20|val-side-v20)  # predictor-v20's run against its equal-sample control on DATA2 (v19_b32) and
      # their start (g19), plain and +mirror, on DATA2's validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT20/val_${EVAL_NAME#eval_}" "$RUNS20/v20_data" "$RUNS19/v19_b32" "$RUNS19/g19" ;;
    retrieval-v20|retrieval-strong-v20|retrieval-side-v20|retrieval-v23|retrieval-strong-v23|retrieval-side-v23|\
    data-v26)  # the GPU stage's data on this CPU (DATA60 [data/proc600v4]): 600 shapes per category at 4 of the 48 grid
      # views each (`data --views-per-shape 4`, split md5 751cbb43... as on the lent machine), about 25 min on 2 cores;
      # resumes. For retrieval from the shapes the twenty-first saw (retrieval-*-v26) and for CPU passes over them
      sketchmesh data --source procedural --shapes-per-category 600 --views 12 --elevations 0 15 30 45 --views-per-shape 4 \
        --workers 2 --out "$DATA60"
      python3 -c "
import hashlib, json
m = json.load(open('$DATA60/manifest.json'))
print('split md5', hashlib.md5(json.dumps([(s['shape_id'], s['split']) for s in m['shapes']]).encode()).hexdigest())" ;;
    generated-v26|generated-mirror-v26)  # generated-v8 and generated-mirror-v9 on DATA60's train split (the same generator,
      # settings and names as the lent machine's), about 7 min each on 2 cores; resume
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      local name=(--name normals16); [ "${1#generated-mirror-}" != "$1" ] && name=(--name normals16_mirror --mirror)
      sketchmesh data generated "$DATA60" --models "$OUT8/models_fifth" "${name[@]}" --workers 2 ;;
    predictor-v26-more)  # the twenty-first (RUNS25/g25b) a pass along a new cosine on DATA60 (the GPU stage's 7,800 shapes at
      # 4 views each, after data-v26 generated-v26 generated-mirror-v26) by the CPU recipe (recipe20) into RUNS25/v26_more:
      # V26_MORE_ITERS [4000], V26_MORE_MINUTES [50] at most, two threads; resumes. Set against its start by val-*-v26-more
      [ -f "$RUNS25/g25b/config.json" ] || { echo "$1 starts from $RUNS25/g25b: run fetch-gpu-v25 first" >&2; exit 1; }
      [ -f "$DATA60/.cache/generated/normals16_mirror/info.json" ] || { echo "$1 reads $DATA60: run data-v26 generated-v26 generated-mirror-v26 first" >&2; exit 1; }
      DATA20=$DATA60 recipe20 "$RUNS25/g25b" "$RUNS25/v26_more" "${V26_MORE_ITERS:-4000}" "${V26_MORE_MINUTES:-50}" 2 ;;
    val-v26-more|val-strong-v26-more|val-side-v26-more)  # predictor-v26-more's run against its start, the twenty-first,
      # plain and +mirror, validation split (OUT26/val_more_*)
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT26/val_more_${EVAL_NAME#eval_}" "$RUNS25/v26_more" "$RUNS25/g25b" ;;
    retrieval-v26|retrieval-strong-v26|retrieval-side-v26)  # retrieval-*-v24's floor from DATA60 (after data-v26): the
      # 7,800 shapes the twenty-first's GPU stage trained on, at their 4 views each, the same samples
      candidate "$1"; eval_case "${1/retrieval-/eval-}"
      sketchmesh eval "$CAND_RUN" --data "$DATA2" --split test --generator-run "$RUNS8/fifth/generator" \
        --retrieval-data "$DATA60" "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 \
        --out "$CAND_OUT/final/retrieval60_${EVAL_NAME#eval_}" ;;
    retrieval-v24|retrieval-strong-v24|retrieval-side-v24)  # the
      # retrieval floor on the same data as the candidate: the nearest of its train views (DATA20's, DATA30's for v23, DATA40's for
      # v24: the shapes it saw) to each test query, the same samples as eval-*-v20 / eval-*-v23
      candidate "$1"; eval_case "${1/retrieval-/eval-}"
      sketchmesh eval "$CAND_RUN" --data "$DATA2" --split test --generator-run "$RUNS8/fifth/generator" \
        --retrieval-data "$CAND_RETRIEVAL" "${EVAL_EXTRA[@]}" --max-samples "$SAMPLES2" --threads 2 \
        --out "$CAND_OUT/final/retrieval_${EVAL_NAME#eval_}" ;;
    cost-both-v20|cost-both-v21|cost-both-v22|cost-both-v23|cost-both-v24|cost-both-v25|cost-both-v26|cost-both-v27)  # the pair bundled before (compare-* takes it from git) and the candidate as shipped, the app's
      # engine with mirror averaging, timed in turn twice each (A B A B) in one window: the machine's speed drifts
      # between windows, and the two predictors are the same network (run it alone: it times)
      candidate "$1"
      [ -f "$CAND_OUT/models_$CAND_PREV_NAME/mesh_predictor.onnx" ] || models_from_git "$CAND_PREV" "$CAND_OUT/models_$CAND_PREV_NAME"
      mkdir -p "$CAND_OUT/same_window"
      for k in 1 2; do
        for m in "$CAND_PREV_NAME:$CAND_OUT/models_$CAND_PREV_NAME" "$CAND_NAME:$CAND_OUT/final/models_fp16"; do
          sketchmesh bench engine --models "${m#*:}" --threads 2 --variants fp32,fp32+mirror --runs 50 \
            --json "$CAND_OUT/same_window/engine_${m%%:*}_$k.json"
        done
      done ;;
    logs-v20)  # predictor-v20's training log beside its control's
      log_summary "$RUNS20" v20_data; log_summary "$RUNS19" v19_b32 ;;
    logs-v21)  # predictor-v20-more's training log beside its start's
      log_summary "$RUNS20" v20_more v20_data ;;
    logs-v22)  # predictor-v21-more's training log beside its start's
      log_summary "$RUNS20" v21_more v20_more ;;
    overfit-v22)  # overfit-v21 for the seventeenth predictor (RUNS20/v21_more) beside the sixteenth
      eval_against train "$OUT22/overfit" "$RUNS20/v21_more" "$RUNS20/v20_more" ;;
    logs-v23)  # predictor-v23's training log beside its start's
      log_summary "$RUNS23" v23_data; log_summary "$RUNS20" v21_more ;;
    overfit-v23)  # overfit-v21 for the DATA30 predictor (RUNS23/v23_data) beside the seventeenth, on DATA2's train split
      # (shapes both saw), to set against the validation split
      eval_against train "$OUT23/overfit" "$RUNS23/v23_data" "$RUNS20/v21_more" ;;
    logs-v24)  # predictor-v24's training log beside its start's
      log_summary "$RUNS24" v24_data; log_summary "$RUNS23" v23_data ;;
    logs-v25)  # predictor-v24-more's training log beside its start's
      log_summary "$RUNS24" v24_more v24_data ;;
    overfit-v25)  # overfit-v21 for the twentieth candidate (RUNS24/v24_more) beside the nineteenth, on DATA2's train split
      eval_against train "$OUT25/overfit" "$RUNS24/v24_more" "$RUNS24/v24_data" ;;
    logs-v26)  # the GPU stage's two calls (g25, g25b) beside its start's log
      log_summary "$RUNS25" g25b g25; log_summary "$RUNS24" v24_more ;;
    overfit-v26)  # overfit-v21 for the twenty-first candidate (RUNS25/g25b) beside the twentieth, on DATA2's train split
      eval_against train "$OUT26/overfit" "$RUNS25/g25b" "$RUNS24/v24_more" ;;
    overfit-v24)  # overfit-v21 for the DATA40 predictor (RUNS24/v24_data) beside the eighteenth, on DATA2's train split
      eval_against train "$OUT24/overfit" "$RUNS24/v24_data" "$RUNS23/v23_data" ;;
    logs-v17)  # predictor-v17's run beside the aligned trial's control and the equal-cost control (when it has run)
      log_summary "$RUNS16" v17_aligned v16_control2 v17_control ;;
    val-v17|val-strong-v17|val-side-v17)  # v17_aligned against the bundled eleventh (v15_control) and the aligned trial's
      # equal-time control (v16_control2), plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT16/val17_${EVAL_NAME#eval_}" "$RUNS16/v17_aligned" "$RUNS16/v16_control2" "$RUNS14/v15_control" ;;
    val-v16b|val-strong-v16b|val-side-v16b)  # the two against v16_control, plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT16/valb_${EVAL_NAME#eval_}" "$RUNS16/v16_damp64" "$RUNS16/v16_lowlr" "$RUNS16/v16_control" ;;
    val-v16|val-strong-v16|val-side-v16)  # the two against their start (v15_control), plain and +mirror, validation split
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT16/val_${EVAL_NAME#eval_}" "$RUNS16/v16_smooth" "$RUNS16/v16_control" "$RUNS14/v15_control" ;;
    folds-v16-smooth|folds-v16-control)  # their folds, counted as folds-v15 counts (clean test sketches, N = 0, mirror)
      local r=v16_${1#folds-v16-}
      export_pair "$RUNS16/$r" "$OUT16/$r" "$OUT8/models_fifth/generator.onnx"
      sketchmesh bench refine --data "$DATA2" --models "$OUT16/$r/models_fp32" --max-samples "$SAMPLES2" --mirror-average \
        --steps 0 --styles clean --out "$OUT16/$r/refine" ;;
    gallery-v16)  # both as the app shows them (mirror averaged), on the gallery's test drawings (after folds-v16-*)
      local r
      for r in v16_smooth v16_control; do
        sketchmesh gallery --data "$DATA2" --models "$OUT16/$r/models_fp32" --mirror-average -o "$OUT16/$r/gallery.png"
      done ;;
    val-v15-all|val-strong-v15-all|val-side-v15-all)  # v15_fold against its control and the tenth (v14_big_mc), +mirror
      local c=${1%-all}; eval_case "${c/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT14/fold/val3_${EVAL_NAME#eval_}" "$RUNS14/v15_fold" "$RUNS14/v15_control" "$RUNS14/v14_big_mc" ;;
    folds-v15-control)  # the control's folds, counted as folds-v15 counts v15_fold's (exported into OUT14/fold_control)
      export_pair "$RUNS14/v15_control" "$OUT14/fold_control" "$OUT8/models_fifth/generator.onnx"
      sketchmesh bench refine --data "$DATA2" --models "$OUT14/fold_control/models_fp32" --max-samples "$SAMPLES2" \
        --mirror-average --steps 0 --styles clean --out "$OUT14/fold_control/refine" ;;
    refine-oracle-v14)  # what the app's outline refinement costs in 3D through its estimated camera: refine-v13 at
      # N = 0 and 3 with each refinement also done in the view's true framed camera (a diagnostic; bench refine --true-camera)
      sketchmesh bench refine --data "$DATA2" --max-samples "$SAMPLES2" --mirror-average --steps 0 3 --true-camera \
        --no-intersections --out "$OUT14/refine_oracle" ;;
    eval-control-mirror-v13|eval-control-strong-mirror-v13|eval-control-side-mirror-v13)  # full minus silhouette-only
      # with mirror averaging: the ninth against its silhouette-only control (control-v10-more), plain and +mirror, test split
      local c=${1/control-/}; eval_case "$c"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$OUT13/control/$EVAL_NAME" "$RUNS10/v10_more" "$RUNS10/v10_silhouette" ;;
    session-v13)  # the app under the pen with its defaults (mirror averaging and refinement on): three scripted sessions
      # in the real window (Xvfb when headless), reports in OUT13/session (run it alone: it times)
      play_sessions "$OUT13/session" ;;
    session-v15|session-v17|session-v18|session-v19|session-v20|session-v21|session-v22|session-v23|session-v24|session-v25|session-v26|session-v27)  # session-v13 with the shipped pair and today's defaults (mirror averaging, refinement,
      # the export's fold repair): three scripted sessions in the real window, reports in CAND_OUT/session (run it alone:
      # it times)
      candidate "$1"; play_sessions "$CAND_OUT/session" ;;
    session-load)  # play_sessions with the bundled pair while two busy loops keep both cores loaded (another job on the
      # artist's laptop), into SESSION_LOAD_OUT [OUT25/session_load]: the UI lag under load, and the worker's
      # composite renders (composite_ms: the opened sketch is a background layer under the strokes)
      busy_start
      play_sessions "${SESSION_LOAD_OUT:-$OUT25/session_load}"
      busy_stop ;;
    session-load-threads)  # session-load's load with ONNX Runtime's intra-op threads set to 2 and to 1 in turn, twice
      # (SKETCHMESH_THREADS), into OUT26/session_load_threads: is the engine's slowdown in the app under load its thread pool?
      local k t
      busy_start
      mkdir -p "$OUT26/session_load_threads"
      for k in 1 2; do
        for t in 2 1; do SKETCHMESH_THREADS=$t play_session "$OUT26/session_load_threads/t${t}_$k.json"; done
      done
      busy_stop ;;
    refine-target)  # the drawing's target outline cut back to its strokes' centre lines (engine.refine.stroke_centre_region)
      # against the whole fill as before: the engines of REFINE_BEFORE [85a8fe0] and REFINE_AFTER [b16a71d, before
      # refine-open's change] by refine_engines into OUT27/refine_target; then the true-camera diagnostic with
      # REFINE_AFTER's engine (val_true_camera; run it alone: it times)
      refine_engines "$OUT27/refine_target" "${REFINE_BEFORE:-85a8fe0}" "${REFINE_AFTER:-b16a71d}"
      # what is left of refinement's 3D cost: the same refinement in each view's true camera, and the engine's camera
      # against it (the diagnostic with REFINE_AFTER's engine; validation split, clean sketches)
      with_engine "${REFINE_AFTER:-b16a71d}" sketchmesh bench refine --data "$DATA2" --split val --max-samples "$SAMPLES2" \
        --mirror-average --steps 0 3 --styles clean --true-camera --out "$OUT27/refine_target/val_true_camera" ;;
    refine-open)  # a drawing without a closed outline left unrefined (engine.refine.refine_prediction) against refined to
      # the generator's silhouette as before: the engine of REFINE_OPEN_BEFORE [b16a71d] and today's by refine_engines
      # into OUT27/refine_open (run it alone: it times)
      refine_engines "$OUT27/refine_open" "${REFINE_OPEN_BEFORE:-b16a71d}" "" ;;
    data-v27)  # DATA70 [data/fresh600v4]: shapes 600-1199 of each category (`data --first-shape 600`: none of them in
      # DATA60, whose 600 per category the twenty-first trained on), their train split only, 4 of the 48 grid views
      # each as the GPU stage rendered; about 20 min on 2 cores; resumes
      sketchmesh data --source procedural --first-shape 600 --shapes-per-category 600 --views 12 --elevations 0 15 30 45 \
        --views-per-shape 4 --splits train --workers 2 --out "$DATA70" ;;
    eval-big-v27|eval-big-strong-v27|eval-big-side-v27|eval-full-v27|eval-full-strong-v27|eval-full-side-v27)  # the
      # bundled twenty-first (import-v27's run, the fifth generator), plain and +mirror, on ten times the test sketches of
      # eval-*-v26 (eval-big: BIG_SAMPLES [1560] evenly spaced over the 139 test shapes' 6,672 views; side views: 1,560
      # of the 1,668 at 0 degrees; OUT27/big/eval_*) or on every one of them (eval-full, 15 and 17 min for clean and
      # strong, 4 for side; OUT27/full/eval_*): how far the 156-sketch figures are from the split's own
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
      local c=${1/big-/} size=big n=${BIG_SAMPLES:-1560}
      [ "${1#eval-full-}" != "$1" ] && { c=${1/full-/}; size=full; n=0; }
      eval_case "$c"; EVAL_EXTRA+=(--mirror-average)
      SAMPLES2=$n eval_against test "$OUT27/$size/$EVAL_NAME" "$RUNS27/twentyfirst/predictor" ;;
    eval-canvas-v29|eval-canvas-strong-v29|eval-canvas-side-v29|eval-image-v29|eval-image-strong-v29|eval-image-side-v29)
      # the bundled twenty-first (import-v27's run, the fifth generator), plain and +mirror, on every test sketch of the
      # case as one of the app's two input paths feeds it to the generator (`eval --sketch-path`): canvas, the drawing's
      # strokes (hand-drawn with strong augmentation) framed on their points at the standard width in full ink; image,
      # the stored raster through the engine's image-file preprocessing. eval-full-*-v27 is the stored rasters' figure.
      # 15-17 min for clean and strong, 4 for side; into OUT29/full/{canvas,image}/eval_*
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
      local path=${1#eval-}; path=${path%%-*}
      local c=${1/$path-/}
      eval_case "$c"; EVAL_EXTRA+=(--mirror-average --sketch-path "$path")
      SAMPLES2=0 eval_against test "$OUT29/full/$path/$EVAL_NAME" "$RUNS27/twentyfirst/predictor" ;;
    eval-scale-v29)  # the same probe on every clean test sketch (15 min): eval-full-v27 with the meshes scaled by 0.98
      # (MESH_SCALE), chosen on DATA72 (check-scale-v29), into OUT29/full/scale/eval_clean
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
      EVAL_EXTRA=(--mirror-average --mesh-scale "${MESH_SCALE:-0.98}")
      SAMPLES2=0 eval_against test "$OUT29/full/scale/eval_clean" "$RUNS27/twentyfirst/predictor" ;;
    fit-damping-v31)  # fit-v6 (the direct fit, 8 views, 1,000 iterations, first training shape of every category) at
      # the large-steps damping FIT_DAMPINGS [2 4 8 16] of the offsets, into OUT31/fit_s{L}.json (6.5-9 min each)
      mkdir -p "$OUT31"
      for l in ${FIT_DAMPINGS:-2 4 8 16}; do
        sketchmesh bench fit --procedural 1 --smoothing "$l" --json "$OUT31/fit_s$l.json"
      done ;;
    overfit-v31)  # issue 14's overfit check (overfit: the default predictor trained 20 min on 13 training shapes, one per
      # category) against direct fits at damping 4 (fit-damping-v31's best mean), into OUT31/overfit (about 27 min)
      sketchmesh bench overfit --set normal_edges=true --out "$OUT31/overfit" --shapes 13 --minutes 20 --iters 4700 --fit-smoothing 4 ;;
    overfit-damping-v31)  # overfit-v31 with the predictor's offset basis damped at 4 instead of 16 (from scratch; the same
      # shapes and their cached fits), into OUT31/overfit_s4
      [ -f "$OUT31/overfit/data/manifest.json" ] || step overfit-v31
      sketchmesh bench overfit --set normal_edges=true --out "$OUT31/overfit_s4" --data "$OUT31/overfit/data" --shapes 13 --minutes 20 --iters 4700 \
        --fit-smoothing 4 --set predictor_smoothing=4 ;;
    overfit-table-v31)  # can the predictor learn one table? overfit-v31 on the first training table alone, rendered at the
      # training data's elevations (0, 15, 30, 45; 96 views), 10 min, against its direct fit at damping 4, into
      # OUT31/overfit_table
      [ -f "$OUT31/table1/manifest.json" ] || sketchmesh data --source procedural --categories table --shapes-per-category 1 \
        --elevations 0 15 30 45 --out "$OUT31/table1"
      sketchmesh bench overfit --set normal_edges=true --out "$OUT31/overfit_table" --data "$OUT31/table1" --shapes 1 --minutes 10 --iters 2350 \
        --fit-smoothing 4 ;;
    overfit-views-v31)  # overfit-table-v31's views and minutes on one shape per category: the first shape of each,
      # rendered at 0, 15, 30 and 45 degrees (the training split holds 12: display_00000 is a test shape), 10 min, against
      # fits at damping 4: is the table lost among the other shapes or at overfit-v31's 30-degree views? Into OUT31/overfit_views
      [ -f "$OUT31/first1/manifest.json" ] || sketchmesh data --source procedural --shapes-per-category 1 \
        --elevations 0 15 30 45 --out "$OUT31/first1"
      sketchmesh bench overfit --set normal_edges=true --out "$OUT31/overfit_views" --data "$OUT31/first1" --shapes 13 --minutes 10 --iters 2350 \
        --fit-smoothing 4 ;;
    overfit-table310-v32)  # steps or sharing? overfit-table-v31's table alone for the 310 iterations it gets in overfit-v31
      # (4,030 iterations / 13 shapes), no time limit, the cosine horizon at 310, no fit (its fit is overfit-table-v31's),
      # into OUT32/overfit_table310 (about 2 min)
      [ -f "$OUT31/table1/manifest.json" ] || step overfit-table-v31
      sketchmesh bench overfit --set normal_edges=true --out "$OUT32/overfit_table310" --data "$OUT31/table1" --shapes 1 --minutes 0 --iters 310 \
        --fit-iters 0 ;;
    overfit-b8-v32)  # overfit-v31 at batch 8 (7 it/s on 2 cores against 3.3 at 32: twice the steps in the same 20 min),
      # the same shapes and their cached fits at damping 4, the cosine horizon at what 20 min hold, into OUT32/overfit_b8
      overfit13 "$OUT32/overfit_b8" --minutes 20 --iters 8400 --batch 8 ;;
    overfit-lr-v32)  # overfit-v31 at twice its peak rate (lr_mesh 4e-3 after the same 100 warm-up steps, batch 32, 20 min),
      # the same shapes and cached fits, into OUT32/overfit_lr4
      overfit13 "$OUT32/overfit_lr4" --minutes 20 --iters 4700 --set lr_mesh=4e-3 ;;
    overfit-long-v32)  # overfit-v31 for twice the time (40 min, the cosine horizon doubled to 9,400 so the rate falls as
      # it did there): does the table stand on legs among the other shapes with more samples, or stay an arch? The same
      # shapes and cached fits, into OUT32/overfit_long (about 42 min)
      overfit13 "$OUT32/overfit_long" --minutes 40 --iters 9400 ;;
    overfit-long-seed-v32)  # overfit-long-v32 with the predictor's seed 1 (as overfit-seed-v32): do the legs at 40 min
      # stand in another run too? Into OUT32/overfit_long_seed1 (about 42 min)
      overfit13 "$OUT32/overfit_long_seed1" --minutes 40 --iters 9400 --set seed=1 ;;
    overfit-seed-v32)  # overfit-v31 again with the predictor's seed 1 (its initial weights and the views it draws; the
      # fits stay seed 0's, cached): the run-to-run spread the variants are read against, into OUT32/overfit_seed1
      overfit13 "$OUT32/overfit_seed1" --minutes 20 --iters 4700 --set seed=1 ;;
    overfit-b512-v33)  # overfit-v31 at batch 512, the lent GPU's batch, for the same samples (4,700 x 32 = 294 x 512;
      # the same peak rate 2e-3, a 10-step warm-up): do 16 times fewer steps cost the table its legs? The same shapes and
      # cached fits, no time limit (this CPU takes half as many samples a second at 512 as at 32: about 35 min), into
      # OUT33/overfit_b512
      overfit13 "$OUT33/overfit_b512" --minutes 0 --iters 294 --batch 512 --set lr_warmup=10 ;;
    overfit-b128-v33)  # overfit-b512-v33 at batch 128 (1,175 steps, a 25-step warm-up): where between 32 and 512 the
      # steps start to matter, no time limit, into OUT33/overfit_b128
      overfit13 "$OUT33/overfit_b128" --minutes 0 --iters 1175 --batch 128 --set lr_warmup=25 ;;
    compare-overfit-v32)  # the 13-shape overfit runs side by side (seconds): overfit-v31 (batch 32, rate 2e-3, 20 min) beside
      # its second seed, its basis damped at 4, batch 8, rate 4e-3 and 40 minutes (both seeds), into OUT32/compare (compare.md/.json/.png,
      # and the table's and the chair's rows); the plot and the table's rows to docs/
      sketchmesh bench overfit-compare "default=$OUT31/overfit" "seed1=$OUT32/overfit_seed1" "damping4=$OUT31/overfit_s4" \
        "batch8=$OUT32/overfit_b8" "lr4e-3=$OUT32/overfit_lr4" "40min=$OUT32/overfit_long" \
        "40min-seed1=$OUT32/overfit_long_seed1" --out "$OUT32/compare" \
        --shape table_00000 --shape chair_00000
      cp "$OUT32/compare/compare.png" docs/overfit_compare.png
      cp "$OUT32/compare/compare_table_00000.png" docs/overfit_table.png ;;
    overfit-b256-v33)  # overfit-b512-v33 at batch 256 (588 steps, a 15-step warm-up): where between 128 and 512 the
      # fewer steps start to cost, no time limit, into OUT33/overfit_b256
      overfit13 "$OUT33/overfit_b256" --minutes 0 --iters 588 --batch 256 --set lr_warmup=15 ;;
    overfit-b128-long-v33)  # overfit-long-v32 at batch 128: its cosine horizon (9,400 / 4 = 2,350 steps) and about its
      # samples (226,880 in 40 min there; 25 min hold them at 128 on this CPU): do the legs come at 128 as at 32? The same
      # shapes and cached fits, into OUT33/overfit_b128_long
      overfit13 "$OUT33/overfit_b128_long" --minutes 25 --iters 2350 --batch 128 --set lr_warmup=25 ;;
    overfit-b512-lr-v33)  # overfit-b512-v33 at four times the peak rate (8e-3: the rate scaled by the square root of the
      # batch's 16 times; a 20-step warm-up): can a larger step make up for the fewer steps? Into OUT33/overfit_b512_lr8
      overfit13 "$OUT33/overfit_b512_lr8" --minutes 0 --iters 294 --batch 512 --set lr_warmup=20 --set lr_mesh=8e-3 ;;
    compare-overfit-v33)  # overfit-v31 (run again on this session's machine) beside batch 128, 256 and 512 (and 512 at
      # 8e-3) for the same samples, and batch 128 for overfit-long-v32's samples (seconds), into OUT33/compare with the
      # table's and the chair's rows; the plot and the table's rows to docs/
      sketchmesh bench overfit-compare "batch32=$OUT31/overfit" "batch128=$OUT33/overfit_b128" \
        "batch256=$OUT33/overfit_b256" "batch512=$OUT33/overfit_b512" "batch512-lr8e-3=$OUT33/overfit_b512_lr8" \
        "batch128-25min=$OUT33/overfit_b128_long" --out "$OUT33/compare" --shape table_00000 --shape chair_00000
      cp "$OUT33/compare/compare.png" docs/overfit_batch.png
      cp "$OUT33/compare/compare_table_00000.png" docs/overfit_batch_table.png ;;
    overfit-sil-v34)  # overfit-v31 with the normal term off (lambda_n 0): full minus silhouette-only on the 13 shapes,
      # the same 4,700 iterations and cached fits, into OUT34/overfit_sil
      overfit13 "$OUT34/overfit_sil" --minutes 0 --iters 4700 --set lambda_n=0 ;;
    overfit-single-v34)  # overfit-v31 supervised from the input view alone (extra_views 0: no other view's silhouette to
      # carve the depth, only the normal image), the same iterations, into OUT34/overfit_single
      overfit13 "$OUT34/overfit_single" --minutes 0 --iters 4700 --set extra_views=0 ;;
    overfit-single-sil-v34)  # overfit-single-v34 silhouette-only: one view's outline and nothing of depth, into
      # OUT34/overfit_single_sil
      overfit13 "$OUT34/overfit_single_sil" --minutes 0 --iters 4700 --set extra_views=0 --set lambda_n=0 ;;
    overfit-interior-v34)  # overfit-v31 with the normal term off the outline (normal_edges false: its gradient reaches the
      # vertices through the covered faces' normals only), the same iterations and fits, into OUT34/overfit_interior
      overfit13 "$OUT34/overfit_interior" --minutes 0 --iters 4700 --set normal_edges=false ;;
    variants-normal-v34)  # the normal term from the start on shapes the predictor never saw: overfit-v31's predictor
      # (the paper's normal term), overfit-interior-v34's (its gradient off the outline) and overfit-sil-v34's
      # (silhouette-only), and full-interior at five times the normal weight (0.01), trained on DATA's training split
      # (data; 30 shapes per category) for 2,000 iterations each (the cosine's horizon; 7-10 min), scored twice on 390
      # test sketches' true normal images, into OUT34/variants
      [ -f "$DATA/manifest.json" ] || step data
      sketchmesh bench variants --data "$DATA" --out "$OUT34/variants" --variant "full-paper:normal_edges=true" \
        --variant "full-interior:normal_edges=false" --variant "silhouette-only:lambda_n=0" \
        --variant "full-interior-x5:normal_edges=false,lambda_n=0.01" --set iters=2000 \
        --minutes 10 --points 2 --max-samples 390 --threads 2
      cp "$OUT34/variants/variants.png" docs/normal_term_test.png ;;
    eval-normal-v34)  # variants-normal-v34's four predictors exported beside the bundled generator (OUT34/models_NAME)
      # and scored from the test split's line drawings through the app's engine, mirror averaged (4 drawings a shape,
      # with retrieval and the template sphere as floors), into OUT34/eval_normal
      drawings_eval "$DATA" yes "$OUT34/variants" "$OUT34/models" "$OUT34/eval_normal" variants-normal-v34 \
        full-paper full-interior silhouette-only full-interior-x5 ;;
    data100-v35)  # DATA's settings (30 degrees, 24 azimuths) at 100 shapes per category (13.4 min on 2 cores), into DATA100
      sketchmesh data --source procedural --shapes-per-category 100 --workers 2 --out "$DATA100" ;;
    variants-data-v35)  # variants-normal-v34's full-interior, silhouette-only and full-interior-x5 trained on DATA100's
      # training split (1,043 shapes against DATA's 312) for the same 2,000 iterations (7 min each), scored twice on
      # 520 of its test split's true normal images (4 a shape), into OUT35/variants
      [ -f "$DATA100/manifest.json" ] || step data100-v35
      sketchmesh bench variants --data "$DATA100" --out "$OUT35/variants" \
        --variant "full-interior:normal_edges=false" --variant "silhouette-only:lambda_n=0" \
        --variant "full-interior-x5:normal_edges=false,lambda_n=0.01" --set iters=2000 \
        --minutes 10 --points 2 --max-samples 520 --threads 2
      cp "$OUT35/variants/variants.png" docs/normal_term_data.png ;;
    eval-data-v35)  # variants-data-v35's three predictors and variants-normal-v34's (trained on 30 shapes per category),
      # each exported beside the bundled generator and scored from DATA100's test drawings: silhouette-only first, so
      # each table's paired differences are full minus silhouette-only at that data size; retrieval (DATA100's training
      # shapes) with the 100-shape predictors, into OUT35/eval_data100 and OUT35/eval_data30
      drawings_eval "$DATA100" yes "$OUT35/variants" "$OUT35/models100" "$OUT35/eval_data100" variants-data-v35 \
        silhouette-only full-interior full-interior-x5
      drawings_eval "$DATA100" no "$OUT34/variants" "$OUT35/models30" "$OUT35/eval_data30" variants-normal-v34 \
        silhouette-only full-interior full-interior-x5 ;;
    variants-data-long-v35)  # variants-data-v35's full-interior and silhouette-only for twice the iterations (4,000, the
      # cosine's horizon; about 17 min each), scored at 10 min and at the end on the same 520 test views, into
      # OUT35/variants_long
      [ -f "$DATA100/manifest.json" ] || step data100-v35
      sketchmesh bench variants --data "$DATA100" --out "$OUT35/variants_long" \
        --variant "full-interior:normal_edges=false" --variant "silhouette-only:lambda_n=0" --set iters=4000 \
        --minutes 20 --points 2 --max-samples 520 --threads 2
      cp "$OUT35/variants_long/variants.png" docs/normal_term_long.png ;;
    eval-data-long-v35)  # variants-data-long-v35's two predictors scored as eval-data-v35 scores its (silhouette-only
      # first), into OUT35/eval_data100_long
      drawings_eval "$DATA100" no "$OUT35/variants_long" "$OUT35/models100long" "$OUT35/eval_data100_long" variants-data-long-v35 \
        silhouette-only full-interior ;;
    eval-gt-data-v35)  # variants-normal-v34's three predictors (30 shapes per category) and variants-data-v35's (100) on
      # DATA100's test split from true normal images, the same 520 views as variants-data-v35 (about 1 min each table),
      # into OUT35/eval_gt30 and OUT35/eval_gt100
      local n r
      for n in 30 100; do
        r=$OUT35/variants; [ "$n" = 30 ] && r=$OUT34/variants
        sketchmesh eval "$r/runs/full-interior" --baseline-run "$r/runs/silhouette-only" \
          --baseline-run "$r/runs/full-interior-x5" --data "$DATA100" --gt-normals --no-retrieval --max-samples 520 \
          --threads 2 --out "$OUT35/eval_gt$n"
      done ;;
    gen-inputs-v35)  # the bundled generator's 64x64 normal images of DATA's training drawings (hand-drawn augmentation
      # 0.5, as the bundled recipe's sets), into DATA/.cache/generated/bundled (resumes)
      [ -f "$DATA/manifest.json" ] || step data
      sketchmesh data generated "$DATA" --models assets/models --name bundled --split train --workers 2 ;;
    variants-gen-v35)  # variants-normal-v34's full-interior and silhouette-only, each reading the bundled generator's
      # images of the drawings (gen-inputs-v35) instead of the true normal images; the targets stay the true images and
      # silhouettes. 2,000 iterations each; the bench's scores (true normal images in) are off these predictors' inputs:
      # eval-gen-v35 scores them from drawings. Into OUT35/variants_gen
      step gen-inputs-v35  # resumes a partial set; seconds when complete
      sketchmesh bench variants --data "$DATA" --out "$OUT35/variants_gen" \
        --variant "full-interior:normal_edges=false" --variant "silhouette-only:lambda_n=0" --set iters=2000 \
        --set input_normals=bundled --minutes 10 --points 2 --max-samples 390 --threads 2 ;;
    eval-gen-v35)  # variants-gen-v35's two predictors scored as eval-data-v35 scores its (DATA100's test drawings,
      # silhouette-only first), into OUT35/eval_gen
      drawings_eval "$DATA100" no "$OUT35/variants_gen" "$OUT35/modelsgen" "$OUT35/eval_gen" variants-gen-v35 \
        silhouette-only full-interior ;;
    gallery-data-v35)  # eval-data-long-v35's two model folders on the same test drawings of the chair, the sofa, the
      # cabinet and the car (two shapes each, mirror averaged as the app runs them; seconds), the per-category bars of
      # eval-gt-data-v35's 100-shape table: to docs/
      local v
      for v in full-interior silhouette-only; do
        [ -f "$OUT35/models100long_$v/mesh_predictor.onnx" ] || step eval-data-long-v35
        sketchmesh gallery --data "$DATA100" --models "$OUT35/models100long_$v" --categories chair sofa cabinet car \
          --per-category 2 --mirror-average --threads 2 -o "docs/normal_term_gallery_$v.png"
      done
      [ -f "$OUT35/eval_gt100/eval_test.png" ] || step eval-gt-data-v35
      cp "$OUT35/eval_gt100/eval_test.png" docs/normal_term_categories.png ;;
    variants-views-v35)  # variants-normal-v34's full-interior and silhouette-only with the input view and one other in
      # the loss (extra_views 1, against 3), on DATA for 2,000 iterations, scored on the same 390 test views' true
      # normal images, into OUT35/variants_views
      [ -f "$DATA/manifest.json" ] || step data
      sketchmesh bench variants --data "$DATA" --out "$OUT35/variants_views" \
        --variant "full-interior-k1:normal_edges=false,extra_views=1" \
        --variant "silhouette-only-k1:lambda_n=0,extra_views=1" --set iters=2000 --minutes 10 --points 2 \
        --max-samples 390 --threads 2 ;;
    legs-v36)  # the legged-furniture specialist, every step in order (about 100 min on 2 cores)
      for s2 in data-v36 generated-v36 generated-mirror-v36 import-v36 predictor-v36-legs export-v36 check-legs-v36 \
                eval-legs-v36 eval-legs-side-v36 gallery-legs-v36; do step "$s2"; done ;;
    legs-more-v36)  # after legs-v36: the specialist trained on as long again, then every measure again with it (45 min)
      for s2 in predictor-v36-legs-more export-v36-more check-legs-v36 eval-legs-v36 eval-legs-side-v36 gallery-legs-v36; do
        step "$s2"
      done ;;
    data-v38)  # DATA38N (bench, chair and table shapes 1250-1549, train split, 4 grid views each: shapes the specialist has
      # not seen, DATA36C's choice shapes 1200-1249 left out), merged with DATA36 into DATA38 (the files hard-linked), and
      # the fifth generator's images of DATA38's drawings and of their flipped drawings; resumes
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      legs_data 1250 "$DATA38N" "$DATA38" "$DATA36" ;;
    predictor-v38-legs-more3)  # the bundled specialist (predictor-v37-legs-more2's run) trained on a fourth time along a new
      # cosine (the same rate and recipe) on DATA38: DATA36's shapes and 300 a category more it has not seen, into
      # RUNS38/legs_more3. V36_ITERS [3000], V36_MINUTES [65] at most; resumes
      [ -f "$DATA38/.cache/generated/normals16_mirror/info.json" ] || step data-v38
      [ -f "$RUNS37/legs_more2/config.json" ] || step predictor-v37-legs-more2
      legs_round "$RUNS37/legs_more2" "$DATA38" "$RUNS38/legs_more3" ;;
    check-legs-v38)  # predictor-v38-legs-more3's run exported as the specialist is (float16 weights, beside the bundled
      # generator; OUT38/models_legs_more3) and scored against the bundled specialist (the third round) on the choice set
      # (DATA36C, 129 unseen legged shapes x 4 views) through the app's engine, mirror averaged, into OUT38/check_legs
      legs_check "$OUT38" "$RUNS38/legs_more3" legs_more3 "$OUT36/models_twentyfirst" "$OUT37/models_legs_more2" ;;
    routed3-v38)  # OUT38/models_routed3: the bundled folder with predictor-v38-legs-more3's specialist in its place
      [ -f "$OUT38/models_legs_more3/mesh_predictor.onnx" ] || step check-legs-v38
      routed_swap "$OUT37/models_routed2" "$OUT38/models_legs_more3" "$OUT38/models_routed3" ;;
    eval-route3-clean-v38|eval-route3-side-v38|eval-route3-strong-v38)  # models_routed3 on the same drawings as
      # eval-route-*-v37 and eval-route2-*-v37 (the eval is deterministic), into OUT38/route3_<case>; its means beside
      # theirs (the twenty-first alone, the first routed folder, the bundled one) and its paired differences from each
      local c=${1#eval-route3-}; c=${c%-v38}
      [ -f "$OUT38/models_routed3/router.onnx" ] || step routed3-v38
      [ -f "$OUT37/route2_$c/eval_models_test.json" ] || step "eval-route2-$c-v37"
      route_eval "$c" "$OUT38/models_routed3" "$OUT38/route3_$c" "$OUT37/route_$c/eval_models_test.json" \
        "$OUT37/route2_$c/eval_models_test.json" ;;
    gallery-route-v38)  # the gallery of eval-route3's folder (one test shape a category, from 30 degrees and from the
      # side, mirror averaged): OUT38/gallery_routed3{,_side}.png, beside OUT37's
      [ -f "$OUT38/models_routed3/router.onnx" ] || step routed3-v38
      route_gallery "$OUT38/models_routed3" "$OUT38/gallery_routed3" ;;
    supports-v38)  # how the meshes stand (`eval --models`' supports table: pieces in the lowest quarter of the height,
      # metrics.support_count): the twenty-first pair and models_routed3, mirror averaged as the app runs them, on
      # DATA36T's legged test shapes at 12 views each (canvas path), with retrieval among DATA36L's unseen shapes of all
      # 13 categories as the reference of real shapes; into OUT38/supports
      [ -f "$OUT38/models_routed3/router.onnx" ] || step routed3-v38
      legs_supports "$OUT38/models_routed3" "$OUT38/supports" ;;
    ship-v38)  # models_routed3's specialist becomes the bundled one (the other three files unchanged)
      [ -f "$OUT38/models_routed3/router.onnx" ] || step routed3-v38
      local f
      for f in generator.onnx mesh_predictor.onnx router.onnx; do cmp "$OUT38/models_routed3/$f" "assets/models/$f"; done
      cp "$OUT38/models_routed3/mesh_predictor_legged.onnx" assets/models/ ;;
    legs-v38)  # the specialist's fourth round, every step in order (about 65 min on 2 cores, one step at a time)
      for s2 in data-v38 predictor-v38-legs-more3 check-legs-v38 routed3-v38 eval-route3-clean-v38 eval-route3-side-v38 \
          eval-route3-strong-v38 gallery-route-v38 supports-v38; do
        step "$s2"
      done ;;
    data-v39)  # DATA39N (bench, chair and table shapes 1550-1849, train split, 4 grid views each) merged with DATA38 into
      # DATA39, and the fifth generator's images (DATA38's rows copied, --reuse); resumes
      [ -f "$DATA38/.cache/generated/normals16_mirror/info.json" ] || step data-v38
      legs_data 1550 "$DATA39N" "$DATA39" "$DATA38" reuse ;;
    predictor-v39-legs-more4)  # predictor-v38-legs-more3's run trained on a fifth time along a new cosine (the same rate and
      # recipe) on DATA39 (300 unseen shapes a category more again), into RUNS39/legs_more4; V36_ITERS [3000], V36_MINUTES
      # [65] at most; resumes
      [ -f "$DATA39/.cache/generated/normals16_mirror/info.json" ] || step data-v39
      [ -f "$RUNS38/legs_more3/config.json" ] || step predictor-v38-legs-more3
      legs_round "$RUNS38/legs_more3" "$DATA39" "$RUNS39/legs_more4" ;;
    check-legs-v39)  # predictor-v39-legs-more4's run exported as the specialist is (OUT39/models_legs_more4) and scored
      # beside the twenty-first and the last two rounds on the choice set (DATA36C) as check-legs-v38, into OUT39/check_legs
      legs_check "$OUT39" "$RUNS39/legs_more4" legs_more4 "$OUT36/models_twentyfirst" "$OUT37/models_legs_more2" \
        "$OUT38/models_legs_more3" ;;
    routed4-v39)  # OUT39/models_routed4: models_routed3 with predictor-v39-legs-more4's specialist in its place
      [ -f "$OUT39/models_legs_more4/mesh_predictor.onnx" ] || step check-legs-v39
      routed_swap "$OUT38/models_routed3" "$OUT39/models_legs_more4" "$OUT39/models_routed4" ;;
    eval-route4-clean-v39|eval-route4-side-v39|eval-route4-strong-v39)  # models_routed4 on the same drawings as
      # eval-route-*-v37 to eval-route3-*-v38, into OUT39/route4_<case>; its means beside theirs and its paired differences
      local c=${1#eval-route4-}; c=${c%-v39}
      [ -f "$OUT39/models_routed4/router.onnx" ] || step routed4-v39
      [ -f "$OUT38/route3_$c/eval_models_test.json" ] || step "eval-route3-$c-v38"
      route_eval "$c" "$OUT39/models_routed4" "$OUT39/route4_$c" "$OUT37/route_$c/eval_models_test.json" \
        "$OUT37/route2_$c/eval_models_test.json" "$OUT38/route3_$c/eval_models_test.json" ;;
    gallery-route-v39)  # the gallery of models_routed4 (as gallery-route-v38): OUT39/gallery_routed4{,_side}.png
      [ -f "$OUT39/models_routed4/router.onnx" ] || step routed4-v39
      route_gallery "$OUT39/models_routed4" "$OUT39/gallery_routed4" ;;
    supports-v39)  # supports-v38 with models_routed4 in place of models_routed3, into OUT39/supports
      [ -f "$OUT39/models_routed4/router.onnx" ] || step routed4-v39
      legs_supports "$OUT39/models_routed4" "$OUT39/supports" ;;
    ship-v39)  # models_routed4's specialist becomes the bundled one (the other three files unchanged)
      [ -f "$OUT39/models_routed4/router.onnx" ] || step routed4-v39
      local f
      for f in generator.onnx mesh_predictor.onnx router.onnx; do cmp "$OUT39/models_routed4/$f" "assets/models/$f"; done
      cp "$OUT39/models_routed4/mesh_predictor_legged.onnx" assets/models/ ;;
    legs-v39)  # the specialist's fifth round, every step in order (after legs-v38; about 70 min on 2 cores)
      for s2 in data-v39 predictor-v39-legs-more4 check-legs-v39 routed4-v39 eval-route4-clean-v39 eval-route4-side-v39 \
          eval-route4-strong-v39 gallery-route-v39 supports-v39; do
        step "$s2"
      done ;;
    data-v40)  # DATA40N (bench, chair and table shapes 1850-2149, train split, 4 grid views each) merged with DATA39 into
      # DATA40S, and the fifth generator's images (DATA39's rows copied, --reuse); resumes
      [ -f "$DATA39/.cache/generated/normals16_mirror/info.json" ] || step data-v39
      legs_data 1850 "$DATA40N" "$DATA40S" "$DATA39" reuse ;;
    predictor-v40-legs-more5)  # predictor-v39-legs-more4's run trained on a sixth time along a new cosine (the same rate and
      # recipe) on DATA40S (300 unseen shapes a category more again), into RUNS40/legs_more5; V36_ITERS [3000], V36_MINUTES
      # [65] at most; resumes
      [ -f "$DATA40S/.cache/generated/normals16_mirror/info.json" ] || step data-v40
      [ -f "$RUNS39/legs_more4/config.json" ] || step predictor-v39-legs-more4
      legs_round "$RUNS39/legs_more4" "$DATA40S" "$RUNS40/legs_more5" ;;
    check-legs-v40)  # predictor-v40-legs-more5's run exported as the specialist is (OUT40/models_legs_more5) and scored
      # beside the twenty-first and the last two rounds on the choice set (DATA36C) as check-legs-v39, into OUT40/check_legs
      legs_check "$OUT40" "$RUNS40/legs_more5" legs_more5 "$OUT36/models_twentyfirst" "$OUT38/models_legs_more3" \
        "$OUT39/models_legs_more4" ;;
    routed5-v40)  # OUT40/models_routed5: models_routed4 with predictor-v40-legs-more5's specialist in its place
      [ -f "$OUT40/models_legs_more5/mesh_predictor.onnx" ] || step check-legs-v40
      routed_swap "$OUT39/models_routed4" "$OUT40/models_legs_more5" "$OUT40/models_routed5" ;;
    eval-route5-clean-v40|eval-route5-side-v40|eval-route5-strong-v40)  # models_routed5 on the same drawings as
      # eval-route-*-v37 to eval-route4-*-v39, into OUT40/route5_<case>; its means beside theirs and its paired differences
      local c=${1#eval-route5-}; c=${c%-v40}
      [ -f "$OUT40/models_routed5/router.onnx" ] || step routed5-v40
      [ -f "$OUT39/route4_$c/eval_models_test.json" ] || step "eval-route4-$c-v39"
      route_eval "$c" "$OUT40/models_routed5" "$OUT40/route5_$c" "$OUT37/route_$c/eval_models_test.json" \
        "$OUT38/route3_$c/eval_models_test.json" "$OUT39/route4_$c/eval_models_test.json" ;;
    gallery-route-v40)  # the gallery of models_routed5 (as gallery-route-v39): OUT40/gallery_routed5{,_side}.png
      [ -f "$OUT40/models_routed5/router.onnx" ] || step routed5-v40
      route_gallery "$OUT40/models_routed5" "$OUT40/gallery_routed5" ;;
    supports-v40)  # supports-v39 with models_routed5 in place of models_routed4, into OUT40/supports
      [ -f "$OUT40/models_routed5/router.onnx" ] || step routed5-v40
      legs_supports "$OUT40/models_routed5" "$OUT40/supports" ;;
    ship-v40)  # models_routed5's specialist becomes the bundled one (the other three files unchanged); nothing to do once
      # ship-compact-v40 has bundled the int8-stored form of models_routed5
      [ -f "$OUT40/models_routed5/router.onnx" ] || step routed5-v40
      if [ -f "$OUT40/models_compact/generator.onnx" ] && cmp -s "$OUT40/models_compact/generator.onnx" assets/models/generator.onnx; then
        echo "ship-v40: assets/models already holds models_compact (ship-compact-v40)"; return 0
      fi
      local f
      for f in generator.onnx mesh_predictor.onnx router.onnx; do cmp "$OUT40/models_routed5/$f" "assets/models/$f"; done
      cp "$OUT40/models_routed5/mesh_predictor_legged.onnx" assets/models/ ;;
    legs-v40)  # the specialist's sixth round, every step in order (after legs-v39; about 65 min on 2 cores)
      for s2 in data-v40 predictor-v40-legs-more5 check-legs-v40 routed5-v40 eval-route5-clean-v40 eval-route5-side-v40 \
          eval-route5-strong-v40 gallery-route-v40 supports-v40; do
        step "$s2"
      done ;;
    compact-v40)  # COMPACT40 with every network's large Conv / Gemm weights stored in int8, one float32 scale per output
      # channel, computed in float32 (engine.bench.compact_model, the `int8w` precision of the benches), into
      # OUT40/models_compact; each file's size before and after
      [ -f "$COMPACT40/mesh_predictor.onnx" ] || [ "$COMPACT40" != "$OUT40/models_routed5" ] || step routed5-v40
      compact_folder "$COMPACT40" "$OUT40/models_compact" ;;
    tradeoff-compact-v40)  # error against run time and size: COMPACT40 as stored and with its weights in int8 (the int8w
      # precision), one pass and mirror averaged, on TRADEOFF_SAMPLES clean test sketches (run it alone: it times)
      [ -f "$COMPACT40/mesh_predictor.onnx" ] || [ "$COMPACT40" != "$OUT40/models_routed5" ] || step routed5-v40
      sketchmesh bench tradeoff --data "$DATA36A" --variant "routed=$COMPACT40" --precisions fp32 int8w fp32+mirror \
        int8w+mirror --bundled "routed:int8w+mirror" --max-samples "$TRADEOFF_SAMPLES" --threads 2 \
        --out "$OUT40/tradeoff_compact" ;;
    eval-compact-clean-v40|eval-compact-side-v40|eval-compact-strong-v40)  # models_compact on the same drawings as
      # eval-route*-v37 to -v40, into OUT40/compact_<case>; its mean beside the twenty-first's and the folder's it was
      # made from (COMPACT40_EVAL_<case>, run first), and the paired differences
      local c=${1#eval-compact-}; c=${c%-v40}
      [ -f "$OUT40/models_compact/mesh_predictor.onnx" ] || step compact-v40
      if [ ! -f "${COMPACT40_EVAL}_$c/eval_models_test.json" ]; then
        [ "$COMPACT40_EVAL" = "$OUT40/route5" ] || { echo "no ${COMPACT40_EVAL}_$c: run the eval of $COMPACT40 first" >&2; return 1; }
        step "eval-route5-$c-v40"
      fi
      route_eval "$c" "$OUT40/models_compact" "$OUT40/compact_$c" "$OUT37/route_$c/eval_models_test.json" \
        "${COMPACT40_EVAL}_$c/eval_models_test.json" ;;
    latency-compact-v40)  # the app's path timed as latency-route-v37 (bench refine, 156 clean and strong test sketches,
      # mirror averaged, outline refinement 0 and 3 steps): COMPACT40, then models_compact (run it alone: it times)
      [ -f "$OUT40/models_compact/mesh_predictor.onnx" ] || step compact-v40
      local m folder
      for m in stored compact; do
        folder=$COMPACT40; [ "$m" = compact ] && folder=$OUT40/models_compact
        sketchmesh bench refine --data "$DATA36A" --models "$folder" --max-samples "$SAMPLES2" --mirror-average \
          --steps 0 3 --no-intersections --threads 2 --quiet --out "$OUT40/latency_$m"
      done ;;
    compact-all-v40)  # the int8-stored folder and every measure of it, one step at a time (about 30 min on 2 cores)
      for s2 in compact-v40 eval-compact-clean-v40 eval-compact-side-v40 eval-compact-strong-v40 tradeoff-compact-v40 \
          latency-compact-v40 supports-compact-v40 gallery-compact-v40; do
        step "$s2"
      done ;;
    supports-compact-v40)  # supports-v40 with models_compact in place of models_routed5, into OUT40/supports_compact
      [ -f "$OUT40/models_compact/mesh_predictor.onnx" ] || step compact-v40
      legs_supports "$OUT40/models_compact" "$OUT40/supports_compact" ;;
    gallery-compact-v40)  # the gallery of models_compact (as gallery-route-v40): OUT40/gallery_compact{,_side}.png
      [ -f "$OUT40/models_compact/mesh_predictor.onnx" ] || step compact-v40
      route_gallery "$OUT40/models_compact" "$OUT40/gallery_compact" ;;
    versus-v40)  # from the JSONs already written: the sixth round minus each earlier column on the choice set
      # (check-legs-v40), and how the bundle's router sent every test drawing of each case (eval-compact-*-v40)
      choice_versus "$OUT40/check_legs/eval_models_train.json"
      local c
      for c in clean side strong; do echo "$c:"; route_counts "$OUT40/compact_$c/eval_models_test.json"; done ;;
    ship-compact-v40)  # models_compact (the bundled folder's networks with int8-stored weights) becomes the bundle: all
      # four files replaced, after ship-v40 (checked: COMPACT40's files are the bundled ones)
      [ -f "$OUT40/models_compact/router.onnx" ] || step compact-v40
      local f
      for f in generator.onnx mesh_predictor.onnx mesh_predictor_legged.onnx router.onnx; do
        cmp -s "$OUT40/models_compact/$f" "assets/models/$f" || cmp "$COMPACT40/$f" "assets/models/$f"
      done
      cp "$OUT40/models_compact/"{generator,mesh_predictor,mesh_predictor_legged,router}.onnx assets/models/ ;;
    data-v41)  # DATA41: airplane, display and lamp shapes 1550-2149 (train split, 4 grid views each; shapes no stage has
      # trained on: the router's are 1300-1549, the choice and retrieval library's 1200-1249), and the fifth generator's
      # images of the drawings and of their flipped drawings; resumes
      fresh_data "$DATA41" "${SECOND[@]}" ;;
    predictor-v41-second)  # a second specialist, as the legged one began (predictor-v36-legs): the twenty-first's
      # predictor trained on airplane, display and lamp alone (DATA41) by the CPU recipe at V36_LR [2e-4] along a new
      # cosine into RUNS41/second: V36_ITERS [3000], V36_MINUTES [65] at most; resumes. Started in the session of
      # 2026-11-29 with the bundle 21 MB under the budget; its choice, router and test steps are the next session's
      [ -f "$DATA41/.cache/generated/normals16_mirror/info.json" ] || step data-v41
      [ -f "$RUNS36/twentyfirst/predictor/config.json" ] || step import-v36
      legs_round "$RUNS36/twentyfirst/predictor" "$DATA41" "$RUNS41/second" ;;
    check-second-v41)  # predictor-v41-second's run exported as the specialists are (float16 weights, beside the twenty-first's
      # generator; OUT41/models_second) and scored beside the twenty-first on its choice set DATA41C (airplane, display
      # and lamp shapes 1200-1249, train split, 4 grid views each) through the app's
      # engine, mirror averaged, into OUT41/check_second; then its paired gain
      [ -f "$RUNS41/second/config.json" ] || step predictor-v41-second
      first_check "$RUNS41/second" "$DATA41C" "$OUT41" second "${SECOND[@]}" ;;
    data-v42|predictor-v42-second2|check-second-v42|second2-v42)  # the second specialist's second round: specialist_round
      specialist_round "$1" second 42 second2 41 second 41 2150 ;;
    router-second-v42)  # how the bundled router (router-v37's run) would route the second specialist's categories: its
      # accuracy and, per threshold, how many airplane, display and lamp drawings of DATA36L (529 unseen shapes, the train
      # split of shapes 1200-1249 of each category, x 4 views and their flipped drawings) it sends to a route of them and
      # how many others; into OUT42/router_second_val.json
      sketchmesh router eval "$RUNS37/router" --data "$DATA36L" --group "${SECOND[@]}" --threads 2 \
        --json "$OUT42/router_second_val.json" ;;
    routed6-v42)  # OUT42/models_routed6: models_routed5 (the bundle before int8 storage) with SECOND42's specialist
      # [OUT42/models_second2] as mesh_predictor_second.onnx and the router exported again from router-v37's run with two
      # routes (the legged three as before; airplane, display and lamp to the new file) at ROUTE_THRESHOLD [0.8]; then the
      # largest difference of its probabilities from models_routed5's router on 64 random images and 8 blank ones
      local pick=${SECOND42:-$OUT42/models_second2}
      [ -f "$pick/mesh_predictor.onnx" ] || step check-second-v42
      [ -f "$OUT40/models_routed5/router.onnx" ] || step routed5-v40
      routed_swap "$OUT40/models_routed5" "$pick" "$OUT42/models_routed6" mesh_predictor_second.onnx
      router_export "$OUT42/models_routed6" "$ROUTES2"
      router_diff "$OUT40/models_routed5" "$OUT42/models_routed6"
      du -b "$OUT42"/models_routed6/*.onnx ;;
    compact6-v42)  # models_routed6 stored as the bundle is (compact_folder: int8 weights, float32 scales) into
      # OUT42/models_compact6; its other files checked byte-equal to the bundle's int8-stored ones (compact-v40)
      [ -f "$OUT42/models_routed6/router.onnx" ] || step routed6-v42
      compact_folder "$OUT42/models_routed6" "$OUT42/models_compact6"
      same_except "$OUT42/models_compact6" "$OUT40/models_compact" router.onnx mesh_predictor_second.onnx ;;
    eval-compact6-clean-v42|eval-compact6-side-v42|eval-compact6-strong-v42)  # models_compact6 on the same drawings as
      # eval-route*-v37 to eval-compact-*-v40, into OUT42/compact6_<case>; its mean beside the twenty-first's and the
      # bundle's (eval-compact-*-v40), the paired differences, and where its router sent the drawings
      local c=${1#eval-compact6-}; c=${c%-v42}
      [ -f "$OUT42/models_compact6/router.onnx" ] || step compact6-v42
      [ -f "$OUT40/compact_$c/eval_models_test.json" ] || step "eval-compact-$c-v40"
      routed_eval "$c" "$OUT42/models_compact6" "$OUT42/compact6_$c" "$OUT37/route_$c/eval_models_test.json" \
        "$OUT40/compact_$c/eval_models_test.json" ;;
    gallery-compact6-v42)  # the gallery of models_compact6 (as gallery-compact-v40): OUT42/gallery_compact6{,_side}.png
      [ -f "$OUT42/models_compact6/router.onnx" ] || step compact6-v42
      route_gallery "$OUT42/models_compact6" "$OUT42/gallery_compact6" ;;
    second-route-v42)  # the second specialist routed, every measure but latency, in order (about 30 min on 2 cores)
      for s2 in router-second-v42 routed6-v42 compact6-v42 eval-compact6-clean-v42 eval-compact6-side-v42 \
          eval-compact6-strong-v42 gallery-compact6-v42; do
        step "$s2"
      done ;;
    versus-v42)  # from the JSONs already written: the second specialist's rounds on their choice set, paired and per
      # category (check-second-v41, check-second-v42), and where models_compact6's router sent every test drawing of each
      # case, route by route (eval-compact6-*-v42)
      choice_versus "$OUT41/check_second/eval_models_train.json"
      choice_versus "$OUT42/check_second/eval_models_train.json"
      case_routes "$ROUTES2" "$OUT42/compact6" ;;
    ship-compact6-v42)  # models_compact6 becomes the bundle: its router and second specialist join the bundled (int8-stored)
      # generator, predictor and legged specialist, checked byte-equal to its own
      [ -f "$OUT42/models_compact6/router.onnx" ] || step compact6-v42
      ship_files "$OUT42/models_compact6" router.onnx mesh_predictor_second.onnx ;;
    data-v43|predictor-v43-second3|check-second-v43)  # the second specialist's third round: specialist_round
      specialist_round "$1" second 43 second3 42 second2 42 2750 "$OUT41/models_second" "$OUT42/models_second2" ;;
    compact7-v43)  # models_routed6 with predictor-v43-second3's specialist as mesh_predictor_second.onnx (OUT43/models_routed7),
      # stored as the bundle is into OUT43/models_compact7; its other files checked byte-equal to models_compact6's
      [ -f "$OUT43/models_second3/mesh_predictor.onnx" ] || step check-second-v43
      [ -f "$OUT42/models_compact6/router.onnx" ] || step compact6-v42
      routed_swap "$OUT42/models_routed6" "$OUT43/models_second3" "$OUT43/models_routed7" mesh_predictor_second.onnx
      compact_folder "$OUT43/models_routed7" "$OUT43/models_compact7"
      same_except "$OUT43/models_compact7" "$OUT42/models_compact6" mesh_predictor_second.onnx ;;
    eval-compact7-clean-v43|eval-compact7-side-v43|eval-compact7-strong-v43)  # models_compact7 on the same drawings as
      # eval-compact6-*-v42, into OUT43/compact7_<case>; its mean beside the twenty-first's, the int8-stored bundle
      # before the second route's (eval-compact-*-v40) and models_compact6's, the paired differences, the routes
      local c=${1#eval-compact7-}; c=${c%-v43}
      [ -f "$OUT43/models_compact7/router.onnx" ] || step compact7-v43
      [ -f "$OUT42/compact6_$c/eval_models_test.json" ] || step "eval-compact6-$c-v42"
      routed_eval "$c" "$OUT43/models_compact7" "$OUT43/compact7_$c" "$OUT37/route_$c/eval_models_test.json" \
        "$OUT40/compact_$c/eval_models_test.json" "$OUT42/compact6_$c/eval_models_test.json" ;;
    gallery-compact7-v43)  # the gallery of models_compact7: OUT43/gallery_compact7{,_side}.png
      [ -f "$OUT43/models_compact7/router.onnx" ] || step compact7-v43
      route_gallery "$OUT43/models_compact7" "$OUT43/gallery_compact7" ;;
    latency-bundle-v43)  # the app's path timed as latency-compact-v40 for BUNDLE43 (bench refine, 156 clean and strong
      # test sketches, mirror averaged, outline refinement 0 and 3 steps; run it alone: it times), into OUT43/latency_bundle
      [ -f "$BUNDLE43/router.onnx" ] || [ "$BUNDLE43" != "$OUT43/models_compact7" ] || step compact7-v43
      bundle_latency "$BUNDLE43" "$OUT43/latency_bundle" ;;
    tradeoff-bundle-v43)  # error against run time for BUNDLE43 as stored (the precision fp32: the files as given) and with
      # dynamic int8 on top, one pass and mirror averaged, on TRADEOFF_SAMPLES clean test sketches, into
      # OUT43/tradeoff_bundle (run it alone: it times)
      [ -f "$BUNDLE43/router.onnx" ] || [ "$BUNDLE43" != "$OUT43/models_compact7" ] || step compact7-v43
      bundle_tradeoff "$BUNDLE43" "$OUT43/tradeoff_bundle" ;;
    docs-v43)  # the README's gallery and error-against-run-time plot, of BUNDLE43: its gallery (as gallery-compact-v40)
      # into OUT43/gallery_bundle{,_side}.png, copied with tradeoff-bundle-v43's plot into docs/
      [ -f "$OUT43/tradeoff_bundle/tradeoff.png" ] || step tradeoff-bundle-v43
      bundle_docs "$BUNDLE43" "$OUT43/gallery_bundle" "$OUT43/tradeoff_bundle" ;;
    second3-v43)  # the second specialist's third round and its measures, in order (about 65 min on 2 cores)
      for s2 in data-v43 predictor-v43-second3 check-second-v43 compact7-v43 eval-compact7-clean-v43 eval-compact7-side-v43 \
          eval-compact7-strong-v43 gallery-compact7-v43; do
        step "$s2"
      done ;;
    versus-v43)  # from the JSONs already written: the third round on the choice set, paired and per category
      # (check-second-v43), and where models_compact7's router sent every test drawing of each case (eval-compact7-*-v43)
      choice_versus "$OUT43/check_second/eval_models_train.json"
      case_routes "$ROUTES2" "$OUT43/compact7" ;;
    ship-compact7-v43)  # models_compact7's second specialist becomes the bundled one (after ship-compact6-v42; the other
      # files checked byte-equal)
      [ -f "$OUT43/models_compact7/router.onnx" ] || step compact7-v43
      ship_files "$OUT43/models_compact7" mesh_predictor_second.onnx ;;
    data-v44)  # DATA44: rifle, watercraft and sofa shapes 1550-2149 (fresh_data: train split, 4 grid views each, shapes no
      # stage has trained on) and the fifth generator's images; resumes
      fresh_data "$DATA44" "${THIRD[@]}" ;;
    predictor-v44-third)  # a third specialist, as the second began (predictor-v41-second): the twenty-first's predictor
      # trained on rifle, watercraft and sofa alone (DATA44) by the CPU recipe at V36_LR [2e-4] along a new cosine into
      # RUNS44/third: V36_ITERS [3000], V36_MINUTES [65] at most; resumes. Started in the session of 2026-11-29 with
      # 12.9 MB of the budget left (one more int8-stored predictor: 8.1 MB); its choice, route and test steps are the
      # next session's
      [ -f "$DATA44/.cache/generated/normals16_mirror/info.json" ] || step data-v44
      [ -f "$RUNS36/twentyfirst/predictor/config.json" ] || step import-v36
      legs_round "$RUNS36/twentyfirst/predictor" "$DATA44" "$RUNS44/third" ;;
    check-third-v44)  # predictor-v44-third's run on its choice set DATA44C (rifle, watercraft and sofa shapes 1200-1249)
      # beside the twenty-first, as check-second-v41 (first_check): OUT44/models_third, OUT44/check_third
      [ -f "$RUNS44/third/config.json" ] || step predictor-v44-third
      first_check "$RUNS44/third" "$DATA44C" "$OUT44" third "${THIRD[@]}" ;;
    router-third-v44)  # how the bundled router (router-v37's run) would route the third specialist's categories: its
      # accuracy and, per threshold, how many rifle, watercraft and sofa drawings of DATA36L (as router-second-v42) it
      # sends to a route of them and how many others; into OUT44/router_third_val.json
      sketchmesh router eval "$RUNS37/router" --data "$DATA36L" --group "${THIRD[@]}" --threads 2 \
        --json "$OUT44/router_third_val.json" ;;
    routed8-v44)  # OUT44/models_routed8: models_routed7 (the bundle before int8 storage) with THIRD44's specialist
      # [OUT44/models_third] as mesh_predictor_third.onnx and the router exported again from router-v37's run with three
      # routes (legged and second as before; rifle, watercraft and sofa to the new file) at ROUTE_THRESHOLD [0.8]; then
      # its probabilities against models_routed7's router (router_diff)
      local pick=${THIRD44:-$OUT44/models_third}
      [ -f "$pick/mesh_predictor.onnx" ] || step check-third-v44
      [ -f "$OUT43/models_routed7/router.onnx" ] || step compact7-v43
      routed_swap "$OUT43/models_routed7" "$pick" "$OUT44/models_routed8" mesh_predictor_third.onnx
      router_export "$OUT44/models_routed8" "$ROUTES3"
      router_diff "$OUT43/models_routed7" "$OUT44/models_routed8"
      du -b "$OUT44"/models_routed8/*.onnx ;;
    compact8-v44)  # models_routed8 stored as the bundle is (compact_folder) into OUT44/models_compact8; its networks but
      # the router and the new specialist checked byte-equal to models_compact7's
      [ -f "$OUT44/models_routed8/router.onnx" ] || step routed8-v44
      [ -f "$OUT43/models_compact7/router.onnx" ] || step compact7-v43
      compact_folder "$OUT44/models_routed8" "$OUT44/models_compact8"
      same_except "$OUT44/models_compact8" "$OUT43/models_compact7" router.onnx mesh_predictor_third.onnx ;;
    eval-compact8-clean-v44|eval-compact8-side-v44|eval-compact8-strong-v44)  # models_compact8 on the same drawings as
      # eval-compact7-*-v43, into OUT44/compact8_<case>; its mean beside the twenty-first's, the int8-stored bundle with
      # the legged route alone (eval-compact-*-v40) and models_compact7's, the paired differences, the three routes
      local c=${1#eval-compact8-}; c=${c%-v44}
      [ -f "$OUT44/models_compact8/router.onnx" ] || step compact8-v44
      [ -f "$OUT43/compact7_$c/eval_models_test.json" ] || step "eval-compact7-$c-v43"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT44/models_compact8" "$OUT44/compact8_$c" \
        "$OUT37/route_$c/eval_models_test.json" "$OUT40/compact_$c/eval_models_test.json" \
        "$OUT43/compact7_$c/eval_models_test.json" ;;
    gallery-compact8-v44)  # the gallery of models_compact8: OUT44/gallery_compact8{,_side}.png
      [ -f "$OUT44/models_compact8/router.onnx" ] || step compact8-v44
      route_gallery "$OUT44/models_compact8" "$OUT44/gallery_compact8" ;;
    third-route-v44)  # the third specialist checked, routed and measured but for latency, in order (about 45 min on 2
      # cores after predictor-v44-third)
      for s2 in check-third-v44 router-third-v44 routed8-v44 compact8-v44 eval-compact8-clean-v44 eval-compact8-side-v44 \
          eval-compact8-strong-v44 gallery-compact8-v44; do
        step "$s2"
      done ;;
    versus-v44)  # from the JSONs already written: the third specialist on its choice set, paired and per category
      # (check-third-v44), and where models_compact8's router sent every test drawing of each case (eval-compact8-*-v44)
      choice_versus "$OUT44/check_third/eval_models_train.json"
      case_routes "$ROUTES3" "$OUT44/compact8" ;;
    latency-bundle-v44)  # the app's path timed for BUNDLE44 (bundle_latency; run it alone) into OUT44/latency_bundle
      [ -f "$BUNDLE44/router.onnx" ] || [ "$BUNDLE44" != "$OUT44/models_compact8" ] || step compact8-v44
      bundle_latency "$BUNDLE44" "$OUT44/latency_bundle" ;;
    tradeoff-bundle-v44)  # error against run time for BUNDLE44 (bundle_tradeoff; run it alone) into OUT44/tradeoff_bundle
      [ -f "$BUNDLE44/router.onnx" ] || [ "$BUNDLE44" != "$OUT44/models_compact8" ] || step compact8-v44
      bundle_tradeoff "$BUNDLE44" "$OUT44/tradeoff_bundle" ;;
    docs-v44)  # the README's gallery and error-against-run-time plot, of BUNDLE44 (bundle_docs): OUT44/gallery_bundle*
      [ -f "$OUT44/tradeoff_bundle/tradeoff.png" ] || step tradeoff-bundle-v44
      bundle_docs "$BUNDLE44" "$OUT44/gallery_bundle" "$OUT44/tradeoff_bundle" ;;
    data-v45|predictor-v45-third2|check-third-v45|third2-v45)  # the third specialist's second round: specialist_round
      specialist_round "$1" third 45 third2 44 third 44 2150 ;;
    compact9-v45)  # models_routed8 with predictor-v45-third2's specialist as mesh_predictor_third.onnx (OUT45/models_routed9),
      # stored as the bundle is into OUT45/models_compact9; its other files checked byte-equal to models_compact8's
      [ -f "$OUT45/models_third2/mesh_predictor.onnx" ] || step check-third-v45
      [ -f "$OUT44/models_compact8/router.onnx" ] || step compact8-v44
      routed_swap "$OUT44/models_routed8" "$OUT45/models_third2" "$OUT45/models_routed9" mesh_predictor_third.onnx
      compact_folder "$OUT45/models_routed9" "$OUT45/models_compact9"
      same_except "$OUT45/models_compact9" "$OUT44/models_compact8" mesh_predictor_third.onnx ;;
    eval-compact9-clean-v45|eval-compact9-side-v45|eval-compact9-strong-v45)  # models_compact9 on the same drawings as
      # eval-compact8-*-v44, into OUT45/compact9_<case>; its mean beside the twenty-first's, eval-compact-*-v40's,
      # models_compact7's and models_compact8's, the paired differences, the three routes
      local c=${1#eval-compact9-}; c=${c%-v45}
      [ -f "$OUT45/models_compact9/router.onnx" ] || step compact9-v45
      [ -f "$OUT44/compact8_$c/eval_models_test.json" ] || step "eval-compact8-$c-v44"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT45/models_compact9" "$OUT45/compact9_$c" \
        "$OUT37/route_$c/eval_models_test.json" "$OUT40/compact_$c/eval_models_test.json" \
        "$OUT43/compact7_$c/eval_models_test.json" "$OUT44/compact8_$c/eval_models_test.json" ;;
    gallery-compact9-v45)  # the gallery of models_compact9: OUT45/gallery_compact9{,_side}.png
      [ -f "$OUT45/models_compact9/router.onnx" ] || step compact9-v45
      route_gallery "$OUT45/models_compact9" "$OUT45/gallery_compact9" ;;
    third2-route-v45)  # the third specialist's second round routed and measured but for latency, in order (about 25 min
      # on 2 cores after third2-v45)
      for s2 in compact9-v45 eval-compact9-clean-v45 eval-compact9-side-v45 eval-compact9-strong-v45 gallery-compact9-v45; do
        step "$s2"
      done ;;
    versus-v45)  # from the JSONs already written: the second round on the choice set, paired and per category
      # (check-third-v45), and where models_compact9's router sent every test drawing of each case (eval-compact9-*-v45)
      choice_versus "$OUT45/check_third/eval_models_train.json"
      case_routes "$ROUTES3" "$OUT45/compact9" ;;
    latency-bundle-v45)  # the app's path timed for BUNDLE45 (bundle_latency; run it alone) into OUT45/latency_bundle
      [ -f "$BUNDLE45/router.onnx" ] || [ "$BUNDLE45" != "$OUT45/models_compact9" ] || step compact9-v45
      bundle_latency "$BUNDLE45" "$OUT45/latency_bundle" ;;
    tradeoff-bundle-v45)  # error against run time for BUNDLE45 (bundle_tradeoff; run it alone) into OUT45/tradeoff_bundle
      [ -f "$BUNDLE45/router.onnx" ] || [ "$BUNDLE45" != "$OUT45/models_compact9" ] || step compact9-v45
      bundle_tradeoff "$BUNDLE45" "$OUT45/tradeoff_bundle" ;;
    docs-v45)  # the README's gallery and error-against-run-time plot, of BUNDLE45 (bundle_docs): OUT45/gallery_bundle*
      [ -f "$OUT45/tradeoff_bundle/tradeoff.png" ] || step tradeoff-bundle-v45
      bundle_docs "$BUNDLE45" "$OUT45/gallery_bundle" "$OUT45/tradeoff_bundle" ;;
    ship-compact9-v45)  # models_compact9's third specialist becomes the bundled one (after ship-compact8-v44; the other
      # files checked byte-equal)
      [ -f "$OUT45/models_compact9/router.onnx" ] || step compact9-v45
      ship_files "$OUT45/models_compact9" mesh_predictor_third.onnx ;;
    data-v46|predictor-v46-third3|check-third-v46|third3-v46)  # the third specialist's third round: specialist_round
      specialist_round "$1" third 46 third3 45 third2 45 2750 "$OUT44/models_third" "$OUT45/models_third2" ;;
    bundle24-v47)  # the twenty-fourth bundle as shipped (git TWENTYFOURTH [3411188], its six files) into OUT47/models_bundle24,
      # and its third specialist beside the twenty-first's generator (git TWENTYFIRST [2a2eadb]) into
      # OUT47/models_bundle_third: on any machine, what the v47 steps start from (the runs of v44-v46 stayed on the machine
      # that trained them: a new machine on 2026-11-29 had none)
      bundle_from_git "${TWENTYFOURTH:-3411188}" "$OUT47/models_bundle24"
      [ -f "$OUT36/models_twentyfirst/generator.onnx" ] || models_from_git "${TWENTYFIRST:-2a2eadb}" "$OUT36/models_twentyfirst"
      rm -rf "$OUT47/models_bundle_third"; mkdir -p "$OUT47/models_bundle_third"
      cp "$OUT36/models_twentyfirst/generator.onnx" "$OUT47/models_bundle_third/"
      cp "$OUT47/models_bundle24/mesh_predictor_third.onnx" "$OUT47/models_bundle_third/mesh_predictor.onnx" ;;
    import-third-v47)  # the bundled third specialist (the second round's, int8-stored) back as a run
      # (RUNS47/bundle_third/predictor: its weights made float32, batch norms calibrated on DATA46's generated images)
      [ -f "$OUT47/models_bundle_third/mesh_predictor.onnx" ] || step bundle24-v47
      [ -f "$DATA46/.cache/generated/normals16_mirror/info.json" ] || step data-v46
      import_run "$OUT47/models_bundle_third" "$RUNS47/bundle_third" "$DATA46" ;;
    predictor-v47-third3)  # the third round as predictor-v46-third3 planned it, on a machine without predictor-v45-third2's
      # run: the bundled third specialist (import-third-v47) trained on along a new cosine by the same recipe and rate on
      # DATA46 into RUNS47/third3; V36_ITERS [3000], V36_MINUTES [65] at most; resumes
      [ -f "$RUNS47/bundle_third/predictor/config.json" ] || step import-third-v47
      legs_round "$RUNS47/bundle_third/predictor" "$DATA46" "$RUNS47/third3" ;;
    check-third-v47)  # predictor-v47-third3's run exported as the specialists are (OUT47/models_third3) and scored beside the
      # twenty-first and the bundled third specialist (as shipped, int8-stored) on the choice set DATA44C (rendered
      # first where missing, as check-third-v44 did), into OUT47/check_third; then its paired gains
      [ -f "$RUNS47/third3/config.json" ] || step predictor-v47-third3
      [ -f "$OUT47/models_bundle_third/mesh_predictor.onnx" ] || step bundle24-v47
      choice_data "$DATA44C" "${THIRD[@]}"
      round_check "$OUT47" "$RUNS47/third3" third3 "$DATA44C" check_third "$OUT36/models_twentyfirst" \
        "$OUT47/models_bundle_third" ;;
    third3-v47)  # the third specialist's third round from the bundle (about 75 min on 2 cores from a bare machine)
      for s2 in bundle24-v47 data-v46 import-third-v47 predictor-v47-third3 check-third-v47; do step "$s2"; done ;;
    data-test-v47)  # DATA36A [data/test100e4] alone (as route-v36 renders it: DATA2's 139 test shapes at 48 views); resumes
      sketchmesh data --source procedural --shapes-per-category 100 --views 12 --elevations 0 15 30 45 --splits test \
        --workers 2 --out "$DATA36A" ;;
    eval-bundle24-clean-v47|eval-bundle24-side-v47|eval-bundle24-strong-v47)  # the twenty-fourth bundle as shipped on
      # every test sketch of the case, into OUT47/bundle24_<case>: eval-compact9-*-v45's figures again on a new machine,
      # and what compact10 is paired against
      local c=${1#eval-bundle24-}; c=${c%-v47}
      [ -f "$OUT47/models_bundle24/router.onnx" ] || step bundle24-v47
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT47/models_bundle24" "$OUT47/bundle24_$c" ;;
    compact10-v47)  # the twenty-fourth bundle with check-third-v47's specialist stored as the bundle is (compact_model: int8
      # weights, one scale per output channel) as mesh_predictor_third.onnx: OUT47/models_compact10; its other files
      # checked byte-equal to the bundle's
      [ -f "$OUT47/models_third3/mesh_predictor.onnx" ] || step check-third-v47
      [ -f "$OUT47/models_bundle24/router.onnx" ] || step bundle24-v47
      compact_swap "$OUT47/models_bundle24" "$OUT47/models_third3" "$OUT47/models_compact10" mesh_predictor_third.onnx ;;
    eval-compact10-clean-v47|eval-compact10-side-v47|eval-compact10-strong-v47)  # models_compact10 on the same drawings as
      # eval-bundle24-*-v47, into OUT47/compact10_<case>; both means, the paired difference, the three routes
      local c=${1#eval-compact10-}; c=${c%-v47}
      [ -f "$OUT47/models_compact10/router.onnx" ] || step compact10-v47
      [ -f "$OUT47/bundle24_$c/eval_models_test.json" ] || step "eval-bundle24-$c-v47"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT47/models_compact10" "$OUT47/compact10_$c" \
        "$OUT47/bundle24_$c/eval_models_test.json" ;;
    gallery-compact10-v47)  # the gallery of models_compact10: OUT47/gallery_compact10{,_side}.png
      [ -f "$OUT47/models_compact10/router.onnx" ] || step compact10-v47
      route_gallery "$OUT47/models_compact10" "$OUT47/gallery_compact10" ;;
    third3-route-v47)  # the third round routed and measured but for latency, each case beside the bundle's own eval of it
      # (which a new machine lacks), clean first (about 65 min on the 2 cores of 2026-11-29 after third3-v47)
      for s2 in data-test-v47 eval-bundle24-clean-v47 compact10-v47 eval-compact10-clean-v47 eval-bundle24-side-v47 \
          eval-compact10-side-v47 eval-bundle24-strong-v47 eval-compact10-strong-v47 gallery-compact10-v47; do
        step "$s2"
      done ;;
    versus-v47)  # from the JSONs already written: the third round on the choice set, paired and per category
      # (check-third-v47), and where models_compact10's router sent every test drawing of each case
      choice_versus "$OUT47/check_third/eval_models_train.json"
      case_routes "$ROUTES3" "$OUT47/compact10" ;;
    latency-bundle-v47|tradeoff-bundle-v47|docs-v47)  # BUNDLE47 timed in the app's path (bundle_latency), its error against run
      # time (bundle_tradeoff; run these two alone) and the README's gallery and plot (bundle_docs), into OUT47
      bundle_round "${1%%-*}" "$BUNDLE47" "$OUT47/models_compact10" compact10-v47 "$OUT47" v47 ;;
    ship-compact10-v47)  # models_compact10's third specialist becomes the bundled one (the other files checked byte-equal)
      [ -f "$OUT47/models_compact10/router.onnx" ] || step compact10-v47
      ship_files "$OUT47/models_compact10" mesh_predictor_third.onnx ;;
    data-v48|predictor-v48-third4|check-third-v48|third4-v48)  # the third specialist's fourth round: specialist_round
      specialist_round "$1" third 48 third4 47 third3 46 3350 ;;
    fast-v48)  # the twenty-fifth bundle (models_compact10) with its generator's decoder made sub-pixel convolutions
      # (engine.graph.subpixel_model: the same arithmetic in another order, checked within 1e-4 of the stored graph; its
      # weights stored as they were): OUT48/models_fast; the other files checked byte-equal
      [ -f "$OUT47/models_compact10/router.onnx" ] || step compact10-v47
      rm -rf "$OUT48/models_fast"; mkdir -p "$OUT48"; cp -r "$OUT47/models_compact10" "$OUT48/models_fast"
      python3 -c 'import sys; from engine.graph import subpixel_model; subpixel_model(sys.argv[1], sys.argv[2])' \
        "$OUT47/models_compact10/generator.onnx" "$OUT48/models_fast/generator.onnx"
      ls -l "$OUT47/models_compact10/generator.onnx" "$OUT48/models_fast/generator.onnx"
      same_except "$OUT48/models_fast" "$OUT47/models_compact10" generator.onnx ;;
    eval-fast-clean-v48|eval-fast-side-v48|eval-fast-strong-v48)  # models_fast on the same drawings as
      # eval-compact10-*-v47 (the twenty-fifth bundle's, run before the engine batched the mirrored drawing), into
      # OUT48/fast_<case>; both means, the paired difference, the three routes
      local c=${1#eval-fast-}; c=${c%-v48}
      [ -f "$OUT48/models_fast/router.onnx" ] || step fast-v48
      [ -f "$OUT47/compact10_$c/eval_models_test.json" ] || step "eval-compact10-$c-v47"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT48/models_fast" "$OUT48/fast_$c" \
        "$OUT47/compact10_$c/eval_models_test.json" ;;
    latency-fast-v48)  # the app's path timed (bundle_latency; run it alone) for models_compact10 and then models_fast, back
      # to back on the same machine, into OUT48/latency_compact10 and OUT48/latency_fast; then each folder's stages
      # (bench engine, fp32 and fp32+mirror, 60 runs) into OUT48/stages_<folder>.json
      [ -f "$OUT48/models_fast/router.onnx" ] || step fast-v48
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      local f
      for f in compact10 fast; do
        local d="$OUT48/models_$f"; [ "$f" = compact10 ] && d="$OUT47/models_compact10"
        bundle_latency "$d" "$OUT48/latency_$f"
        sketchmesh bench engine --models "$d" --variants fp32,fp32+mirror --runs 60 --threads 2 \
          --json "$OUT48/stages_$f.json"
      done ;;
    profile-generator-v48)  # where the generator's time goes, by operator, for models_compact10's and models_fast's
      # (ONNX Runtime's profiler, 2 threads, 30 runs of one drawn test sketch after 3 untimed; run it alone)
      [ -f "$OUT48/models_fast/router.onnx" ] || step fast-v48
      python3 - "$OUT47/models_compact10/generator.onnx" "$OUT48/models_fast/generator.onnx" <<'PY'
import collections, json, os, sys, tempfile
import numpy as np
import onnxruntime as ort
from engine.preprocess import rasterize_strokes
from engine.strokes import Stroke
t = np.linspace(0, 2 * np.pi, 80)
x = rasterize_strokes([Stroke(np.stack([200 + 90 * np.cos(t), 150 + 60 * np.sin(t)], 1)),
                       Stroke([[130, 150], [270, 160]])])[None, None].astype(np.float32)
for path in sys.argv[1:]:
    so = ort.SessionOptions()
    so.intra_op_num_threads, so.inter_op_num_threads = 2, 1
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.enable_profiling = True
    so.profile_file_prefix = os.path.join(tempfile.mkdtemp(), "gen")
    sess = ort.InferenceSession(path, so, providers=["CPUExecutionProvider"])
    name = sess.get_inputs()[0].name
    for _ in range(33):
        sess.run(None, {name: x})
    events = json.load(open(sess.end_profiling()))
    starts = sorted(e["ts"] for e in events if e.get("name") == "model_run")
    ops = collections.defaultdict(float)
    for e in events:  # the first 3 runs untimed
        if e.get("cat") == "Node" and e["name"].endswith("_kernel_time") and e["ts"] >= starts[3]:
            ops[e["args"]["op_name"]] += e["dur"] / 1e3 / 30
    top = ", ".join(f"{k} {v:.1f}" for k, v in sorted(ops.items(), key=lambda kv: -kv[1])[:7])
    print(f"{path}: {sum(ops.values()):.1f} ms of operators a run (30 runs); {top}")
PY
      ;;
    versus-fast-v48)  # from the JSONs already written: every test drawing's voxel IoU, models_fast against models_compact10,
      # case by case: how many drawings differ at all, the largest difference, and how many were routed differently
      python3 - "$OUT47/compact10" "$OUT48/fast" <<'PY'
import json, sys
old, new = sys.argv[1:]
for case in ("clean", "side", "strong"):
    try:
        a, b = (json.load(open(f"{d}_{case}/eval_models_test.json")) for d in (old, new))
    except FileNotFoundError as exc:
        print(f"{case}: {exc.filename} missing")
        continue
    ca, cb = a["columns"][0], b["columns"][0]
    views = {(r["shape_id"], v["view"]): v for r in a["rows"] for v in r["per_view"]}
    diffs, routes, n = [], 0, 0
    for r in b["rows"]:
        for v in r["per_view"]:
            w = views[(r["shape_id"], v["view"])]
            diffs.append(abs(v["iou"][cb] - w["iou"][ca]))
            routes += v["routes"][cb]["route"] != w["routes"][ca]["route"]
            n += 1
    print(f"{case}: {n} drawings, {sum(d > 0 for d in diffs)} with a different voxel IoU (largest difference "
          f"{max(diffs):.2g}), {routes} routed differently")
PY
      ;;
    latency-app-v48)  # the app's default path timed (bench refine, 156 clean and strong test sketches, mirror averaged,
      # 0 and 3 refinement steps, folds repaired; run it alone) for BUNDLE48: first with the engine of commit BEFORE48
      # [a6f9420] (its engine, training and sketchmesh packages from git, first on PYTHONPATH), which checked every
      # refined mesh again for the fold repair, into OUT48/latency_app_before; then with this one into OUT48/latency_app
      [ -f "$BUNDLE48/router.onnx" ] || [ "$BUNDLE48" != "$OUT48/models_fast" ] || step fast-v48
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      local before="$OUT48/code_before"
      rm -rf "$before"; mkdir -p "$before"
      git archive "${BEFORE48:-a6f9420}" engine training sketchmesh | tar -x -C "$before"
      PYTHONPATH="$before" python3 -P -m sketchmesh bench refine --data "$DATA36A" --models "$BUNDLE48" \
        --max-samples "$SAMPLES2" --mirror-average --steps 0 3 --repair-folds --no-intersections --threads 2 --quiet \
        --out "$OUT48/latency_app_before"
      sketchmesh bench refine --data "$DATA36A" --models "$BUNDLE48" --max-samples "$SAMPLES2" --mirror-average \
        --steps 0 3 --repair-folds --no-intersections --threads 2 --quiet --out "$OUT48/latency_app" ;;
    fast-route-v48)  # models_fast measured: the three cases (paired against the twenty-fifth bundle's evals), latency, the
      # error-against-run-time table, the docs and the export path before and after the repair's shortcuts (about 55 min
      # on 2 cores)
      for s2 in fast-v48 eval-fast-clean-v48 eval-fast-side-v48 eval-fast-strong-v48 latency-fast-v48 \
          profile-generator-v48 versus-fast-v48 tradeoff-bundle-v48 docs-v48 latency-app-v48; do
        step "$s2"
      done ;;
    latency-app-v49)  # the refinement's speed-ups (batched, one-winding rasterization; the broad phase's flags) timed in the
      # app's path (bench refine, 156 clean and strong test sketches, mirror averaged, 0 and 3 refinement steps; run it
      # alone) on BUNDLE49: the engine of commit BEFORE49 [772e40f] (its engine package from git, first on PYTHONPATH;
      # this bench, which times the camera fit inside the refinement) then this one, the live path (no fold repair)
      # into OUT49/latency_live_before and OUT49/latency_live, then the export path (folds repaired) into
      # OUT49/latency_export_before and OUT49/latency_export
      local before="$OUT49/engine_before"
      rm -rf "$before"; mkdir -p "$before"
      git archive "${BEFORE49:-772e40f}" engine | tar -x -C "$before"
      local path extra
      for path in live export; do
        extra=(); [ "$path" = export ] && extra=(--repair-folds)
        PYTHONPATH="$before" python3 -P -m sketchmesh bench refine --data "$DATA36A" --models "$BUNDLE49" \
          --max-samples "$SAMPLES2" --mirror-average --steps 0 3 "${extra[@]}" --no-intersections --threads 2 --quiet \
          --out "$OUT49/latency_${path}_before"
        sketchmesh bench refine --data "$DATA36A" --models "$BUNDLE49" --max-samples "$SAMPLES2" --mirror-average \
          --steps 0 3 "${extra[@]}" --no-intersections --threads 2 --quiet --out "$OUT49/latency_$path"
      done ;;
    data-v49|predictor-v49-third5|check-third-v49|third5-v49)  # the third specialist's fifth round: specialist_round
      specialist_round "$1" third 49 third5 48 third4 48 3950 ;;
    compact12-v49|eval-compact12-clean-v49|eval-compact12-side-v49|eval-compact12-strong-v49|gallery-compact12-v49|\
        third5-route-v49|versus-v49|ship-compact12-v49)  # the third specialist's fifth round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" third 49 third5 compact12 48 compact11 ;;
    preprocess-v50)  # bench engine's stages (fp32, 2 threads, 60 runs of the bundled sample images: decoding, thinning and
      # the redraw with draw_segments are its preprocess stage) with the engine of commit BEFORE50 [f4b0db9: draw_segments
      # before it computed in place] and with today's, into OUT50/preprocess_before.json and _after.json, then both
      # preprocess stages (run it alone: it times)
      mkdir -p "$OUT50"
      with_engine "${BEFORE50:-f4b0db9}" sketchmesh bench engine --variants fp32 --runs 60 --threads 2 \
        --json "$OUT50/preprocess_before.json"
      sketchmesh bench engine --variants fp32 --runs 60 --threads 2 --json "$OUT50/preprocess_after.json"
      python3 - "$OUT50/preprocess_before.json" "$OUT50/preprocess_after.json" <<'EOF'
import json, sys
for f in sys.argv[1:]:
    r = {x["stage"]: x for x in json.load(open(f)) if x["variant"] == "fp32"}
    print(f"{f}: preprocess p50 {r['preprocess']['p50_ms']:.2f} ms (p95 {r['preprocess']['p95_ms']:.2f}), "
          f"total p50 {r['total']['p50_ms']:.1f} ms, {r['preprocess']['sketches']} sketches")
EOF
      ;;
    data-v50|predictor-v50-third6|check-third-v50|third6-v50)  # the third specialist's sixth round: specialist_round
      specialist_round "$1" third 50 third6 49 third5 49 4550 ;;
    compact13-v50|eval-compact13-clean-v50|eval-compact13-side-v50|eval-compact13-strong-v50|gallery-compact13-v50|\
        third6-route-v50|versus-v50|ship-compact13-v50)  # the third specialist's sixth round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" third 50 third6 compact13 49 compact12 ;;
    legged-v51)  # the bundled legged specialist (the sixth round's, int8-stored) beside the twenty-first's generator as a
      # model folder, OUT51/models_bundle_legged: what its seventh round starts from on a machine without its runs (the
      # v36-v40 runs stayed on the machine that trained them)
      rm -rf "$OUT51/models_bundle_legged"; mkdir -p "$OUT51/models_bundle_legged"
      cp "$OUT36/models_twentyfirst/generator.onnx" "$OUT51/models_bundle_legged/"
      cp assets/models/mesh_predictor_legged.onnx "$OUT51/models_bundle_legged/mesh_predictor.onnx" ;;
    data-v51)  # DATA51: bench, chair and table shapes 2150-2749 (train split, 4 grid views each; no stage has seen them;
      # the legged rounds' earlier data is not on this machine, so these alone), and the fifth generator's images of its
      # drawings and of their flipped drawings; resumes
      sketchmesh data --source procedural --first-shape 2150 --shapes-per-category 600 --categories "${LEGS[@]}" \
        --views 12 --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$DATA51"
      sketchmesh data generated "$DATA51" --models "$OUT8/models_fifth" --name normals16 --workers 2
      sketchmesh data generated "$DATA51" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2 ;;
    import-legs-v51)  # the bundled legged specialist back as a run (RUNS51/bundle_legged/predictor: its weights made
      # float32, batch norms calibrated on DATA51's generated images)
      [ -f "$OUT51/models_bundle_legged/mesh_predictor.onnx" ] || step legged-v51
      [ -f "$DATA51/.cache/generated/normals16_mirror/info.json" ] || step data-v51
      import_run "$OUT51/models_bundle_legged" "$RUNS51/bundle_legged" "$DATA51" ;;
    predictor-v51-legs7)  # the legged specialist's seventh round: the bundled one (import-legs-v51) trained on along a
      # new cosine by the same recipe and rate on DATA51, into RUNS51/legs7; V36_ITERS [3000], V36_MINUTES [65] at most;
      # resumes
      [ -f "$RUNS51/bundle_legged/predictor/config.json" ] || step import-legs-v51
      legs_round "$RUNS51/bundle_legged/predictor" "$DATA51" "$RUNS51/legs7" ;;
    check-legs-v51)  # predictor-v51-legs7's run exported as the specialists are (OUT51/models_legs7) and scored beside the
      # twenty-first and the bundled legged specialist (as shipped, int8-stored) on its choice set DATA36C (rendered first
      # where missing), into OUT51/check_legs; then its paired gains
      [ -f "$RUNS51/legs7/config.json" ] || step predictor-v51-legs7
      [ -f "$OUT51/models_bundle_legged/mesh_predictor.onnx" ] || step legged-v51
      choice_data "$DATA36C" "${LEGS[@]}"
      legs_check "$OUT51" "$RUNS51/legs7" legs7 "$OUT36/models_twentyfirst" "$OUT51/models_bundle_legged" ;;
    legs7-v51)  # the legged specialist's seventh round (data, import, training, the choice set; about 3 hours on 2 cores)
      for s2 in legged-v51 data-v51 import-legs-v51 predictor-v51-legs7 check-legs-v51; do step "$s2"; done ;;
    compact14-v51|eval-compact14-clean-v51|eval-compact14-side-v51|eval-compact14-strong-v51|gallery-compact14-v51|\
        legs7-route-v51|versus-v51|ship-compact14-v51)  # the legged specialist's seventh round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" legs 51 legs7 compact14 50 compact13 ;;
    latency-bundle-v52|tradeoff-bundle-v52|docs-v52)  # BUNDLE52 [assets/models: the thirtieth bundle once
      # ship-compact14-v51 has run] timed in the app's path (bundle_latency), its error against run time (bundle_tradeoff;
      # run these two alone) and the README's gallery and plot (bundle_docs), into OUT52
      bundle_round "${1%%-*}" "$BUNDLE52" "$OUT51/models_compact14" compact14-v51 "$OUT52" v52 ;;
    data-v52|predictor-v52-legs8|check-legs-v52|legs8-v52)  # the legged specialist's eighth round: specialist_round
      specialist_round "$1" legs 52 legs8 51 legs7 51 2750 ;;
    logs-v52)  # the seventh and eighth legged rounds' logs (log_summary: iterations, minutes over the sittings, the
      # silhouette term at the start and the end)
      log_summary "$RUNS51" legs7
      log_summary "$RUNS52" legs8 ;;
    compact15-v52|eval-compact15-clean-v52|eval-compact15-side-v52|eval-compact15-strong-v52|gallery-compact15-v52|\
        legs8-route-v52|versus-v52|ship-compact15-v52)  # the legged specialist's eighth round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" legs 52 legs8 compact15 51 compact14 ;;
    latency-bundle-v53|tradeoff-bundle-v53|docs-v53)  # BUNDLE53 [assets/models: the thirty-first bundle once
      # ship-compact15-v52 has run] timed in the app's path (bundle_latency), its error against run time (bundle_tradeoff;
      # run these two alone) and the README's gallery and plot (bundle_docs), into OUT53
      bundle_round "${1%%-*}" "$BUNDLE53" "$OUT52/models_compact15" compact15-v52 "$OUT53" v53 ;;
    data-calib-v53)  # DATACAL: the train split of 8 procedural shapes a category (13 categories) from shape 9000 on, 4 views
      # each at 30 degrees: drawings the test split never holds, to calibrate the int8 generator's ranges; resumes
      sketchmesh data --source procedural --shapes-per-category 8 --first-shape 9000 --views-per-shape 4 --splits train \
        --workers 2 --out "$DATACAL" ;;
    int8gen-v53)  # the thirty-first bundle (models_compact15) with its generator's convolutions in int8 beside it
      # (quantize-generator: static, calibrated on 96 DATACAL drawings, half strongly augmented; the first and last
      # convolutions and those under 16 x 16 pixels as stored), which the engine runs in place of generator.onnx:
      # OUT53/models_int8gen; the other files checked byte-equal
      [ -f "$OUT52/models_compact15/router.onnx" ] || step compact15-v52
      [ -f "$DATACAL/manifest.json" ] || step data-calib-v53
      rm -rf "$OUT53/models_int8gen"; mkdir -p "$OUT53/models_int8gen"
      cp "$OUT52/models_compact15/"*.onnx "$OUT53/models_int8gen/"
      sketchmesh quantize-generator "$OUT53/models_int8gen" --data "$DATACAL"
      same_except "$OUT53/models_int8gen" "$OUT52/models_compact15" generator_int8.onnx ;;
    eval-int8gen-clean-v53|eval-int8gen-side-v53|eval-int8gen-strong-v53)  # models_int8gen on every test sketch of the
      # case beside the thirty-first bundle's eval (eval-compact15-<case>-v52): both means, the paired difference, routes
      local c=${1#eval-int8gen-}; c=${c%-v53}
      [ -f "$OUT53/models_int8gen/generator_int8.onnx" ] || step int8gen-v53
      [ -f "$OUT52/compact15_$c/eval_models_test.json" ] || step "eval-compact15-$c-v52"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT53/models_int8gen" "$OUT53/int8gen_$c" \
        "$OUT52/compact15_$c/eval_models_test.json" ;;
    gallery-int8gen-v53)
      [ -f "$OUT53/models_int8gen/generator_int8.onnx" ] || step int8gen-v53
      route_gallery "$OUT53/models_int8gen" "$OUT53/gallery_int8gen" ;;
    int8gen-route-v53)  # the int8 generator made and measured on every test sketch (about 25 min on 2 cores)
      for s2 in int8gen-v53 eval-int8gen-clean-v53 eval-int8gen-side-v53 eval-int8gen-strong-v53 gallery-int8gen-v53; do
        step "$s2"
      done ;;
    latency-int8gen-v53)  # the app's path timed (bundle_latency; run it alone) for models_compact15 and then
      # models_int8gen, back to back, into OUT53/latency_compact15 and OUT53/latency_int8gen; then each folder's stages
      # (bench engine, fp32 and fp32+mirror, 60 runs) into OUT53/stages_<name>.json
      [ -f "$OUT53/models_int8gen/generator_int8.onnx" ] || step int8gen-v53
      local f d
      for f in compact15 int8gen; do
        d="$OUT53/models_$f"; [ "$f" = compact15 ] && d="$OUT52/models_compact15"
        bundle_latency "$d" "$OUT53/latency_$f"
        sketchmesh bench engine --models "$d" --variants fp32,fp32+mirror --runs 60 --threads 2 \
          --json "$OUT53/stages_$f.json"
      done ;;
    ship-int8gen-v53)  # models_int8gen's generator_int8.onnx into assets/models (the other files checked byte-equal)
      [ -f "$OUT53/models_int8gen/generator_int8.onnx" ] || step int8gen-v53
      ship_files "$OUT53/models_int8gen" generator_int8.onnx ;;
    data-v53|predictor-v53-legs9|check-legs-v53|legs9-v53)  # the legged specialist's ninth round: specialist_round
      specialist_round "$1" legs 53 legs9 52 legs8 52 3350 ;;
    compact16-v53|eval-compact16-clean-v53|eval-compact16-side-v53|eval-compact16-strong-v53|gallery-compact16-v53|\
        legs9-route-v53|versus-v53|ship-compact16-v53)  # the legged specialist's ninth round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" legs 53 legs9 compact16 53 int8gen ;;  # on the bundle with the int8 generator
    latency-bundle-v54|tradeoff-bundle-v54|docs-v54)  # BUNDLE54 [assets/models: the thirty-second bundle once
      # ship-compact16-v53 has run] timed in the app's path (bundle_latency), its error against run time (bundle_tradeoff;
      # run these two alone) and the README's gallery and plot (bundle_docs), into OUT54
      bundle_round "${1%%-*}" "$BUNDLE54" "$OUT53/models_compact16" compact16-v53 "$OUT54" v54 ;;
    data-v54|predictor-v54-legs10|check-legs-v54|legs10-v54)  # the legged specialist's tenth round: specialist_round,
      # 2,400 iterations [V36_ITERS] and 75 minutes at most [V36_MINUTES] to fit one session (about 66 minutes alone)
      V36_ITERS=${V36_ITERS:-2400} V36_MINUTES=${V36_MINUTES:-75} specialist_round "$1" legs 54 legs10 53 legs9 53 3950 ;;
    compact17-v54|eval-compact17-clean-v54|eval-compact17-side-v54|eval-compact17-strong-v54|gallery-compact17-v54|\
        legs10-route-v54|versus-v54|ship-compact17-v54)  # the legged specialist's tenth round routed, measured and
      # shipped on the thirty-third bundle: specialist_route
      specialist_route "$1" legs 54 legs10 compact17 53 compact16 ;;
    logs-v54)  # the tenth legged round's log (log_summary)
      log_summary "$RUNS54" legs10 ;;
    bundle34-v55)  # the thirty-fourth bundle as shipped (git THIRTYFOURTH [09ba02f], its seven files) into BUNDLE55: what the
      # v55 steps measure and change, on any machine
      bundle_from_git "${THIRTYFOURTH:-09ba02f}" "$BUNDLE55" ;;
    data-v55)  # the router's drawings on a new machine: DATA36L (its validation, as route-v36 renders it) and DATA37 with
      # the fifth generator's images of both (data-v37); resumes
      sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --views 12 --elevations 0 15 30 45 \
        --views-per-shape 4 --splits train --workers 2 --out "$DATA36L"
      step data-v37 ;;
    data-strong-v55)  # the fifth generator's images of DATA37's and DATA36L's drawings strongly augmented (broken,
      # doubled, wobbly lines: --augment-strength 1.0, another seed), normals16_strong: what a router reads from a rough
      # drawing; resumes
      [ -f "$DATA37/.cache/generated/normals16_mirror/done.npy" ] || step data-v55
      local d
      for d in "$DATA37" "$DATA36L"; do
        sketchmesh data generated "$d" --models "$OUT8/models_fifth" --name normals16_strong --augment-strength 1.0 \
          --seed 1 --workers 2
      done ;;
    router-v55)  # a wider router (ROUTER_CHANNELS [32 64 96 128], about 190,000 parameters) trained as router-v37
      # trained the bundled one (ROUTER_EPOCHS [30]) on DATA37's images of the drawings, the flipped drawings and the
      # strongly augmented drawings (data-strong-v55) into RUNS55/router_wide; scored on DATA36L's; resumes
      [ -f "$DATA37/.cache/generated/normals16_strong/done.npy" ] || step data-strong-v55
      # shellcheck disable=SC2086
      sketchmesh router train --data "$DATA37" --val-data "$DATA36L" --inputs normals16 normals16_mirror normals16_strong \
        --group "${LEGS[@]}" --epochs "${ROUTER_EPOCHS:-30}" --channels ${ROUTER_CHANNELS:-32 64 96 128} --threads 2 \
        --out "$RUNS55/router_wide" ;;
    routed-v55)  # OUT55/models_router: BUNDLE55 with router-v55's router (the same three routes) at ROUTE_THRESHOLD55
      # [0.8], every other file byte-equal; then both routers' tables on DATA36L (router_table)
      [ -f "$RUNS55/router_wide/config.json" ] || step router-v55
      [ -f "$BUNDLE55/router.onnx" ] || step bundle34-v55
      rm -rf "$OUT55/models_router"; cp -r "$BUNDLE55" "$OUT55/models_router"
      rm -f "$OUT55/models_router/README.md" "$OUT55/models_router/__init__.py"
      sketchmesh router export "$RUNS55/router_wide" --models "$OUT55/models_router" \
        --route "mesh_predictor_legged.onnx=$(IFS=,; echo "${LEGS[*]}")" \
        --route "mesh_predictor_second.onnx=$(IFS=,; echo "${SECOND[*]}")" \
        --route "mesh_predictor_third.onnx=$(IFS=,; echo "${THIRD[*]}")" --threshold "${ROUTE_THRESHOLD55:-0.8}"
      same_except "$OUT55/models_router" "$BUNDLE55" router.onnx
      router_table "$DATA36L" "$BUNDLE55" "$OUT55/models_router" | tee "$OUT55/router_table.txt"
      ROUTER_TABLE_INPUTS=normals16_strong router_table "$DATA36L" "$BUNDLE55" "$OUT55/models_router" \
        | tee "$OUT55/router_table_strong.txt" ;;
    eval-router-clean-v55|eval-router-side-v55|eval-router-strong-v55)  # routed-v55's folder on every test sketch of
      # the case beside BUNDLE55's (eval-bundle-<case>-v55): both means, the paired difference, where the drawings went
      local c=${1#eval-router-}; c=${c%-v55}
      [ -f "$OUT55/models_router/router.onnx" ] || step routed-v55
      [ -f "$OUT55/bundle_$c/eval_models_test.json" ] || step "eval-bundle-$c-v55"
      ROUTE_GROUPS=$ROUTES3 routed_eval "$c" "$OUT55/models_router" "$OUT55/router_$c" \
        "$OUT55/bundle_$c/eval_models_test.json" ;;
    ship-router-v55)  # routed-v55's router.onnx into assets/models (the other networks checked byte-equal): the thirty-fifth
      # bundle
      [ -f "$OUT55/models_router/router.onnx" ] || step routed-v55
      ship_files "$OUT55/models_router" router.onnx ;;
    latency-bundle-v55|tradeoff-bundle-v55|docs-v55)  # routed-v55's folder (the thirty-fifth bundle's files) timed in the
      # app's path (bundle_latency), its error against run time (bundle_tradeoff; run these two alone) and the README's
      # gallery and plot (bundle_docs), into OUT55
      bundle_round "${1%%-*}" "$OUT55/models_router" "$OUT55/models_router" routed-v55 "$OUT55" v55 ;;
    latency-bundle34-v55)  # BUNDLE55 (the thirty-fourth bundle) timed in the app's path as latency-bundle-v55 times the
      # thirty-fifth (bundle_latency; run it alone, then latency-bundle-v55 straight after) into OUT55/latency_bundle34
      [ -f "$BUNDLE55/router.onnx" ] || step bundle34-v55
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      bundle_latency "$BUNDLE55" "$OUT55/latency_bundle34" ;;
    router-cost-v55)  # what each router adds to a drawing, the thirty-fourth bundle's and routed-v55's, as router-cost-v37
      # measures it (2 threads, p50 of 500 passes after 20 to warm up, alternating; run it alone)
      [ -f "$OUT55/models_router/router.onnx" ] || step routed-v55
      python3 - "$BUNDLE55" "$OUT55/models_router" <<'PY'
import sys, time
import numpy as np
from engine.models import load_router
routers = [load_router(f"{d}/router.onnx", 2) for d in sys.argv[1:]]
x = np.random.default_rng(0).random((1, 3, 64, 64), dtype=np.float32)
runs = [[] for _ in routers]
for _ in range(520):
    for r, out in zip(routers, runs):
        t = time.perf_counter(); r.session.run(None, {r.input_name: x}); out.append(time.perf_counter() - t)
for d, out in zip(sys.argv[1:], runs):
    print(f"{d}/router.onnx: router pass p50 {np.median(out[20:]) * 1e3:.3f} ms")
PY
      ;;
    bundle35-v56)  # the thirty-fifth bundle as shipped (git THIRTYFIFTH [d62d7f6], its seven files) into BUNDLE56
      bundle_from_git "${THIRTYFIFTH:-d62d7f6}" "$BUNDLE56" ;;
    data-val-v56)  # the router's validation drawings on a new machine: DATA36L (as data-v55 renders it) and the fifth
      # generator's images of them and of their flipped drawings (what data-v37 makes of DATA36L; without DATA37); resumes
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --views 12 --elevations 0 15 30 45 \
        --views-per-shape 4 --splits train --workers 2 --out "$DATA36L"
      sketchmesh data generated "$DATA36L" --models "$OUT8/models_fifth" --name normals16 --workers 2
      sketchmesh data generated "$DATA36L" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2 ;;
    mirror-v56)  # OUT56/models_mirror: BUNDLE56 with its router set to route on the drawing and its flip (sketchmesh
      # router set --mirror: the metadata alone changes), every network byte-equal but router.onnx, whose probabilities
      # are checked the same (router_diff); then both ways tabled on DATA36L's plain and flipped drawings (router_table)
      [ -f "$BUNDLE56/router.onnx" ] || step bundle35-v56
      [ -f "$DATA36L/.cache/generated/normals16_mirror/done.npy" ] || step data-val-v56
      router_variant "$BUNDLE56" "$OUT56/models_mirror" --mirror
      router_diff "$BUNDLE56" "$OUT56/models_mirror"
      router_table "$DATA36L" "$BUNDLE56" "$OUT56/models_mirror" | tee "$OUT56/router_table.txt" ;;
    eval-bundle-clean-v56|eval-bundle-side-v56|eval-bundle-strong-v56)  # BUNDLE56 on every test sketch of the case
      # (route_eval) into OUT56/bundle_<case>, and where its router sent the drawings
      local c=${1#eval-bundle-}; c=${c%-v56}
      bundle_eval "$BUNDLE56" bundle35-v56 "$c" "$OUT56/bundle_$c" ;;
    eval-mirror-clean-v56|eval-mirror-side-v56|eval-mirror-strong-v56|eval-mirror06-clean-v56|eval-mirror06-side-v56|\
        eval-mirror06-strong-v56|eval-plain06-clean-v56|eval-plain06-side-v56|eval-plain06-strong-v56)  # a v56 folder on
      # every test sketch of the case beside the earlier ones (variant_eval): mirror-v56's beside BUNDLE56's
      # (eval-bundle-<case>-v56), mirror06-v56's beside both, plain06-v56's beside BUNDLE56's and mirror06-v56's
      local k=${1#eval-} c; k=${k%-v56}; c=${k##*-}; k=${k%-*}
      case $k in
        mirror) variant_eval mirror mirror-v56 "$c" bundle ;;
        mirror06) variant_eval mirror06 mirror06-v56 "$c" bundle mirror ;;
        plain06) variant_eval plain06 plain06-v56 "$c" bundle mirror06 ;;
      esac ;;
    mirror06-v56)  # OUT56/models_mirror06: mirror-v56's folder at the threshold ROUTE_THRESHOLD56 [0.6], where the
      # validation table (mirror-v56, OUT56/router_table.txt) puts mirror routing's best expected gain (averaging two
      # drawings' probabilities makes the router less sure, so a lower threshold suits it)
      [ -f "$OUT56/models_mirror/router.onnx" ] || step mirror-v56
      router_variant "$OUT56/models_mirror" "$OUT56/models_mirror06" --threshold "${ROUTE_THRESHOLD56:-0.6}" ;;
    plain06-v56)  # OUT56/models_plain06: BUNDLE56 at the threshold ROUTE_THRESHOLD56 [0.6] without mirror routing: what
      # the lower threshold alone does (beside mirror-v56: mirror routing alone)
      [ -f "$BUNDLE56/router.onnx" ] || step bundle35-v56
      router_variant "$BUNDLE56" "$OUT56/models_plain06" --threshold "${ROUTE_THRESHOLD56:-0.6}" ;;
    mirror-v56-all)  # the mirror-routing round in order (about 75 minutes on 2 cores)
      for s2 in bundle35-v56 data-test-v47 data-val-v56 mirror-v56 eval-bundle-clean-v56 eval-mirror-clean-v56 \
          eval-bundle-strong-v56 eval-mirror-strong-v56 eval-bundle-side-v56 eval-mirror-side-v56 mirror06-v56 \
          eval-mirror06-clean-v56 eval-mirror06-strong-v56 eval-mirror06-side-v56 plain06-v56 eval-plain06-clean-v56 \
          eval-plain06-strong-v56 eval-plain06-side-v56; do
        step "$s2"
      done ;;
    ship-mirror-v56)  # mirror06-v56's router.onnx (mirror routing at 0.6; the same network) into assets/models (the
      # other networks checked byte-equal): the thirty-sixth bundle
      [ -f "$OUT56/models_mirror06/router.onnx" ] || step mirror06-v56
      ship_files "$OUT56/models_mirror06" router.onnx ;;
    latency-bundle-v56|tradeoff-bundle-v56|docs-v56)  # mirror06-v56's folder (the thirty-sixth bundle's files) timed in
      # the app's path (bundle_latency), its error against run time (bundle_tradeoff; run these two alone) and the
      # README's gallery and plot (bundle_docs), into OUT56
      bundle_round "${1%%-*}" "$OUT56/models_mirror06" "$OUT56/models_mirror06" mirror06-v56 "$OUT56" v56 ;;
    mirror-cost-v56)  # what mirror routing adds to a drawing: the bundle's router on one image and on the two the
      # engine routes with route_mirror (2 threads, p50 of 500 passes after 20 to warm up, alternating; run it alone)
      [ -f "$BUNDLE56/router.onnx" ] || step bundle35-v56
      python3 - "$BUNDLE56/router.onnx" <<'PY'
import sys, time
import numpy as np
from engine.models import load_router
r = load_router(sys.argv[1], 2)
x = np.random.default_rng(0).random((2, 3, 64, 64), dtype=np.float32)
runs = {1: [], 2: []}
for _ in range(520):
    for n, out in runs.items():
        t = time.perf_counter(); r.session.run(None, {r.input_name: x[:n]}); out.append(time.perf_counter() - t)
for n, out in runs.items():
    print(f"{sys.argv[1]}: router pass on {n} image{'s' if n > 1 else ''} p50 {np.median(out[20:]) * 1e3:.3f} ms")
PY
      ;;
    latency-bundle35-v56)  # BUNDLE56 (the thirty-fifth bundle) timed in the app's path as latency-bundle-v56 times the
      # thirty-sixth (bundle_latency; run it alone, then latency-bundle-v56 straight after) into OUT56/latency_bundle35
      [ -f "$BUNDLE56/router.onnx" ] || step bundle35-v56
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      bundle_latency "$BUNDLE56" "$OUT56/latency_bundle35" ;;
    router-v55-all)  # the router round in order (about 75 minutes on 2 cores): the bundle's own figures, the oracle, the
      # wider router, its routing and its test figures
      for s2 in bundle34-v55 data-v55 eval-bundle-clean-v55 eval-bundle-side-v55 eval-bundle-strong-v55 oracle-clean-v55 \
          data-strong-v55 router-v55 routed-v55 eval-router-clean-v55 eval-router-side-v55 eval-router-strong-v55; do
        step "$s2"
      done ;;
    eval-bundle-clean-v55|eval-bundle-side-v55|eval-bundle-strong-v55)  # BUNDLE55 on every test sketch of the case
      # (route_eval) into OUT55/bundle_<case>, and where its router sent the drawings
      local c=${1#eval-bundle-}; c=${c%-v55}
      bundle_eval "$BUNDLE55" bundle34-v55 "$c" "$OUT55/bundle_$c" ;;
    only-legs-clean-v55|only-second-clean-v55|only-third-clean-v55|only-legs-side-v55|only-second-side-v55|\
        only-third-side-v55|only-legs-strong-v55|only-second-strong-v55|only-third-strong-v55)  # one of BUNDLE55's
      # specialists alone (OUT55/models_only_<kind>: the bundle's generator files and the specialist as mesh_predictor.onnx,
      # no router) on every test sketch of its own categories (subset_data of DATA36A) in the case, as route_eval
      # measures: what an oracle router would get there, into OUT55/only_<kind>_<case>
      local k=${1#only-} c f cats; k=${k%-v55}; c=${k#*-}; k=${k%%-*}
      case $k in
        legs) f=mesh_predictor_legged.onnx; cats=("${LEGS[@]}") ;;
        second) f=mesh_predictor_second.onnx; cats=("${SECOND[@]}") ;;
        third) f=mesh_predictor_third.onnx; cats=("${THIRD[@]}") ;;
      esac
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      [ -f "$BUNDLE55/router.onnx" ] || step bundle34-v55
      subset_data "$DATA36A" "data/test100e4_$k" "${cats[@]}"
      rm -rf "$OUT55/models_only_$k"; mkdir -p "$OUT55/models_only_$k"
      cp "$BUNDLE55"/generator*.onnx "$OUT55/models_only_$k/"
      cp "$BUNDLE55/$f" "$OUT55/models_only_$k/mesh_predictor.onnx"
      DATA36A="data/test100e4_$k" route_eval "$c" "$OUT55/models_only_$k" "$OUT55/only_${k}_$c" ;;
    oracle-clean-v55|oracle-side-v55|oracle-strong-v55)  # how much a perfect router would add to BUNDLE55 in the case: its
      # routed eval against every drawing of a specialist's categories sent to that specialist (route_oracle; about 11 +
      # 9 minutes on 2 cores clean, a quarter of that side)
      local c=${1#oracle-} k; c=${c%-v55}
      [ -f "$OUT55/bundle_$c/eval_models_test.json" ] || step "eval-bundle-$c-v55"
      for k in legs second third; do
        [ -f "$OUT55/only_${k}_$c/eval_models_test.json" ] || step "only-$k-$c-v55"
      done
      route_oracle "$OUT55/bundle_$c/eval_models_test.json" \
        "mesh_predictor_legged.onnx=$OUT55/only_legs_$c/eval_models_test.json" \
        "mesh_predictor_second.onnx=$OUT55/only_second_$c/eval_models_test.json" \
        "mesh_predictor_third.onnx=$OUT55/only_third_$c/eval_models_test.json" | tee "$OUT55/oracle_$c.txt" ;;
    mirror-output-v53)  # mirror averaging without the generator's second pass, an ad hoc variant against what the app runs
      # (nothing shipped): the generator's image of the drawing flipped left to right as the flipped drawing's (its red
      # channel, the view-frame x, mirrored as a - r with a the foreground coverage, hard (max channel > 0.02) or from the
      # blue channel (min(1, 2 b)); without the mirroring of red as a check of the sign) against the app's mirror
      # averaging and one pass; BUNDLE53's models on SAMPLES2 [156] clean test sketches of DATA36A, voxel IoU (the mean of
      # the categories) and p50 time of each; into OUT53/mirror_output/mirror_output.json. Run it alone: it times
      mkdir -p "$OUT53/mirror_output"
      python3 - "$BUNDLE53" "$DATA36A" "$SAMPLES2" "$OUT53/mirror_output/mirror_output.json" <<'PY'
import json, os, sys, time
from collections import defaultdict
from pathlib import Path
import numpy as np
from engine import contract as C
from engine.icosphere import mirror_average
from engine.mesh import Mesh
from engine.pipeline import SketchEngine, _run_batch, assemble_mesh, downsample_normals
from training.data.dataset import ShapeViewDataset
from training.evaluation.evaluate import _pair_metrics, world_vertices
from training.evaluation.metrics import solid_voxels
models, data_dir, samples, out = sys.argv[1], Path(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4])
data = ShapeViewDataset(data_dir, "test", extra_views=0, augment_strength=0.0)
idx = np.unique(np.linspace(0, len(data) - 1, samples).round().astype(int))
app = SketchEngine(models, threads=2, cache_size=0, mirror_average=True); app.load()
one = SketchEngine(models, threads=2, cache_size=0, mirror_average=False); one.load()

def flipped_image(n, mode):  # n: (1, 3, H, W) encoded normals of the drawing -> those of its mirror image
    f = n[..., ::-1].copy()
    a = (f.max(axis=1) > 0.02).astype(np.float32) if mode == "hard" else np.minimum(1.0, 2.0 * f[:, 2])
    if mode != "no sign":
        f[:, 0] = np.clip(a - f[:, 0], 0.0, 1.0)
    return f

def output_mirror(raster, mode):  # the app's _run_models with the flipped drawing's image made from the drawing's
    (n,) = _run_batch(app._generator, [C.GENERATOR_OUTPUT], raster[None, None].astype(np.float32))
    n = np.clip(n, 0.0, 1.0).astype(np.float32)
    small = np.concatenate([downsample_normals(n), downsample_normals(flipped_image(n, mode))])
    route, _ = app._route(small[:1])
    p = app._specialist(route) if route is not None else app._predictor
    local, glob = _run_batch(p, p.output_names, small)
    m = [assemble_mesh(local[i:i + 1], glob[i:i + 1], p.template_level, p.template_radius) for i in range(2)]
    return Mesh(mirror_average(m[0].vertices, m[1].vertices).astype(np.float32), m[0].faces)

variants = {"the app's mirror averaging (the flipped drawing through both networks)": lambda sk, r: app.predict(sk).mesh,
            "one pass": lambda sk, r: one.predict(sk).mesh,
            "generator's image mirrored, coverage hard": lambda sk, r: output_mirror(r, "hard"),
            "generator's image mirrored, coverage from blue": lambda sk, r: output_mirror(r, "blue"),
            "generator's image mirrored, red not mirrored (the sign check)": lambda sk, r: output_mirror(r, "no sign")}
gt, iou, ms = {}, defaultdict(lambda: defaultdict(list)), defaultdict(list)
for i in idx:
    it = data[int(i)]
    sk, cam16 = it["sketch"][0].numpy(), it["camera"].numpy().astype(np.float64)
    key = (it["category"], it["shape_id"])
    if key not in gt:
        mesh = data.load_mesh(*key)
        gt[key] = (mesh, solid_voxels(mesh, 32, True))
    raster = app.predict(sk).sketch  # also the warm-up of this drawing's route
    for name, fn in variants.items():
        t0 = time.perf_counter()
        mesh = fn(sk, raster)
        ms[name].append((time.perf_counter() - t0) * 1e3)
        world = Mesh(world_vertices(np.asarray(mesh.vertices, np.float64), cam16), mesh.faces)
        iou[name][it["category"]].append(_pair_metrics(world, gt[key][0], gt[key][1], 32, True)["voxel_iou"])
rows = [{"variant": k, "voxel_iou": float(np.mean([np.mean(v) for v in iou[k].values()])),
         "ms_p50": float(np.median(ms[k])), "ms_p90": float(np.percentile(ms[k], 90))} for k in variants]
print(f"{len(idx)} clean test sketches, 2 threads:")
for r in rows:
    print(f"  {r['variant']}: voxel IoU {r['voxel_iou']:.4f}, {r['ms_p50']:.1f} ms p50 (p90 {r['ms_p90']:.1f})")
tmp = out.with_suffix(".tmp")
tmp.write_text(json.dumps({"models": models, "samples": len(idx), "rows": rows}, indent=1))
os.replace(tmp, out)
PY
      ;;
    profile-generator-v53)  # where the generator's time goes: BUNDLE53's generator.onnx in the engine's session options
      # (2 threads) with onnxruntime's profiler, 25 runs of a batch of two sparse random drawings (the app's mirror
      # batch), kernel time per operator type (ms a run, share, nodes); into OUT53/profile_generator.json. Run it alone
      mkdir -p "$OUT53"
      python3 - "$BUNDLE53/generator.onnx" "$OUT53/profile_generator.json" <<'PY'
import collections, json, os, sys, tempfile
import numpy as np
import onnxruntime as ort
from engine.models import _session_options
path, out = sys.argv[1], sys.argv[2]
runs = 25
so = _session_options(2)
so.enable_profiling = True
so.profile_file_prefix = os.path.join(tempfile.mkdtemp(), "generator")
session = ort.InferenceSession(path, sess_options=so, providers=["CPUExecutionProvider"])
name = session.get_inputs()[0].name
x = (np.random.default_rng(0).random((2, 1, 256, 256)) > 0.97).astype(np.float32)
for _ in range(runs):
    session.run(None, {name: x})
events = json.load(open(session.end_profiling()))
us, nodes = collections.Counter(), collections.Counter()
for e in events:
    if e.get("cat") == "Node" and e["name"].endswith("_kernel_time"):
        us[e["args"]["op_name"]] += e["dur"]
        nodes[e["args"]["op_name"]] += 1
total = sum(us.values())
rows = [{"op": op, "ms_per_run": t / runs / 1e3, "share": t / total, "nodes": nodes[op] // runs} for op, t in us.most_common()]
print(f"{path}: {total / runs / 1e3:.1f} ms of kernels a run (batch of two, 2 threads)")
for r in rows:
    print(f"  {r['op']:24s} {r['ms_per_run']:6.2f} ms  {100 * r['share']:5.1f} %  {r['nodes']} nodes")
with open(out + ".tmp", "w") as fh:
    json.dump({"model": path, "runs": runs, "rows": rows}, fh, indent=1)
os.replace(out + ".tmp", out)
PY
      ;;
    logs-v53)  # the eighth and ninth legged rounds' logs (log_summary)
      log_summary "$RUNS52" legs8
      log_summary "$RUNS53" legs9 ;;
    latency-bundle-v51|tradeoff-bundle-v51|docs-v51)  # BUNDLE51 [assets/models: the twenty-ninth bundle once
      # ship-compact13-v50 has run] timed in the app's path (bundle_latency), its error against run time (bundle_tradeoff;
      # run these two alone) and the README's gallery and plot (bundle_docs), into OUT51
      bundle_round "${1%%-*}" "$BUNDLE51" "$OUT50/models_compact13" compact13-v50 "$OUT51" v51 ;;
    latency-bundle-v50|tradeoff-bundle-v50|docs-v50)  # BUNDLE50 [assets/models: the twenty-eighth bundle once
      # ship-compact12-v49 has run] timed in the app's path (bundle_latency), its error against run time (bundle_tradeoff;
      # run these two alone) and the README's gallery and plot (bundle_docs), into OUT50
      bundle_round "${1%%-*}" "$BUNDLE50" "$OUT49/models_compact12" compact12-v49 "$OUT50" v50 ;;
    tradeoff-bundle-v49|docs-v49)  # BUNDLE49 [assets/models: the twenty-seventh bundle once ship-compact11-v48 has run]:
      # its error against run time (bundle_tradeoff; run it alone) and the README's gallery and plot (bundle_docs), into
      # OUT49
      bundle_round "${1%%-*}" "$BUNDLE49" "$OUT48/models_compact11" compact11-v48 "$OUT49" v49 ;;
    refine-v49)  # the outline refinement on BUNDLE49 against its step count N (bench refine: 0 1 2 3 4 6 steps, 156 clean and
      # 156 strong test sketches, mirror averaged, the camera fit inside the refinement's time; run it alone: it times),
      # into OUT49/refine, its plot copied to docs/refine.png
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      sketchmesh bench refine --data "$DATA36A" --models "$BUNDLE49" --max-samples "$SAMPLES2" --mirror-average \
        --threads 2 --out "$OUT49/refine"
      cp "$OUT49/refine/refine.png" docs/refine.png ;;
    session-v49)  # the app under the pen with the bundled models, in turn with the app and engine of commit BEFORE49
      # [772e40f] (the outline refinement on when the app starts; from git, first on PYTHONPATH) and with today's
      # defaults (the refinement off since 2026-11-30; mirror averaging and the export's fold repair on): three scripted
      # sessions each in the real window, reports OUT49/session/before_k.json and after_k.json, then their table (run
      # it alone: it times)
      local before="$OUT49/app_before" i
      rm -rf "$before"; mkdir -p "$before" "$OUT49/session"
      git archive "${BEFORE49:-772e40f}" app engine | tar -x -C "$before"
      for i in 1 2 3; do
        PYTHONPATH="$before" play_session "$OUT49/session/before_$i.json"
        play_session "$OUT49/session/after_$i.json"
      done
      session_table "$OUT49/session" ;;
    penup-v50)  # the app under the pen on a blank canvas with the inference controller of commit BEFORE50W [5e079de:
      # every change waited the 100 ms debounce] and with today's (the first change after a pause sent at once):
      # file_sessions into OUT50/penup
      file_sessions penup worker.py "${BEFORE50W:-5e079de}" blank_session ;;
    erase-v50|session-v50)  # the app under the pen, erase-v50 on a blank canvas, session-v50 with the bundled sample
      # opened as the background layer (play_session), with the canvas of commit BEFORE50E [05c7ec9: every repaint
      # built each stroke's path point by point, every eraser move resampled every stroke in its box with a Python loop
      # a segment] and with today's (each committed stroke's path built once while it lives; only strokes within the
      # eraser's reach resampled, in numpy; the pieces the eraser leaves made of the stroke's own points and the cuts,
      # not of the dense samples): file_sessions into OUT50/erase or OUT50/session, its table with the erase phase's
      # worst stall
      local play=blank_session
      [ "$1" = session-v50 ] && play=play_session
      file_sessions "${1%-v50}" canvas.py "${BEFORE50E:-05c7ec9}" "$play" ;;
    strokes-v49)  # the app under the pen on a blank canvas (the engine is sent the strokes, not an image), with the
      # engine of commit BEFORE49S [1dee70c] (every update rasterized every stroke; from git, first on PYTHONPATH) and with
      # today's (engine.preprocess.StrokeRasterizer: only the strokes added since the last update): three scripted
      # sessions each in the real window, reports OUT49/strokes/before_k.json and after_k.json, then their table (run
      # it alone: it times)
      local before="$OUT49/strokes_before" i
      rm -rf "$before"; mkdir -p "$before" "$OUT49/strokes"
      git archive "${BEFORE49S:-1dee70c}" engine | tar -x -C "$before"
      for i in 1 2 3; do
        PYTHONPATH="$before" blank_session "$OUT49/strokes/before_$i.json"
        blank_session "$OUT49/strokes/after_$i.json"
      done
      session_table "$OUT49/strokes" ;;
    ship-fast-v48)  # models_fast's generator becomes the bundled one (the other files checked byte-equal)
      [ -f "$OUT48/models_fast/router.onnx" ] || step fast-v48
      ship_files "$OUT48/models_fast" generator.onnx ;;
    compact11-v48|eval-compact11-clean-v48|eval-compact11-side-v48|eval-compact11-strong-v48|gallery-compact11-v48|\
        third4-route-v48|versus-v48|ship-compact11-v48)  # the third specialist's fourth round
      # routed, measured and shipped: specialist_route
      specialist_route "$1" third 48 third4 compact11 48 fast ;;
    latency-bundle-v48|tradeoff-bundle-v48|docs-v48)  # BUNDLE48 timed in the app's path (bundle_latency), its error against run
      # time (bundle_tradeoff; run these two alone) and the README's gallery and plot (bundle_docs), into OUT48
      bundle_round "${1%%-*}" "$BUNDLE48" "$OUT48/models_fast" fast-v48 "$OUT48" v48 ;;
    ship-compact8-v44)  # models_compact8's router and third specialist join the bundle (after ship-compact7-v43; the other
      # files checked byte-equal)
      [ -f "$OUT44/models_compact8/router.onnx" ] || step compact8-v44
      ship_files "$OUT44/models_compact8" router.onnx mesh_predictor_third.onnx ;;
    route-all-v37)  # the router and the routed pair, then every measure (after data-v37 and legs-more-v36; ~50 min)
      for s2 in router-v37 routed-v37 eval-route-clean-v37 eval-route-side-v37 eval-route-strong-v37 gallery-route-v37 \
          latency-route-v37; do
        step "$s2"
      done ;;
    ship-v37)  # a routed folder becomes the app's bundled models: router.onnx and mesh_predictor_legged.onnx join the
      # twenty-first pair in assets/models (the two networks' files unchanged). SHIP37 [OUT37/models_routed2]: the
      # specialist's third round, chosen on DATA36C (check-legs-v37); OUT37/models_routed was bundled first (04871e1)
      local folder=${SHIP37:-$OUT37/models_routed2}
      [ -f "$folder/router.onnx" ] || step routed2-v37
      cmp "$folder/generator.onnx" assets/models/generator.onnx
      cmp "$folder/mesh_predictor.onnx" assets/models/mesh_predictor.onnx
      cp "$folder/router.onnx" "$folder/mesh_predictor_legged.onnx" assets/models/ ;;
    router-v37)  # the category router (training.model.router) trained on DATA37's generated images (and their flipped
      # drawings'), ROUTER_EPOCHS [30] epochs, into RUNS37/router; scored on DATA36L's (50 other shapes a category): its
      # accuracy and, per threshold, how many legged drawings it sends to the specialist and how many others; resumes
      [ -f "$DATA37/.cache/generated/normals16_mirror/done.npy" ] || step data-v37
      sketchmesh router train --data "$DATA37" --val-data "$DATA36L" --group "${LEGS[@]}" --epochs "${ROUTER_EPOCHS:-30}" \
        --threads 2 --out "$RUNS37/router"
      sketchmesh router eval "$RUNS37/router" --data "$DATA36L" --group "${LEGS[@]}" --threads 2 --json "$OUT37/router_val.json"
      python3 - "$OUT37/router_val.json" <<'PY'
import json, sys
# expected gain of a threshold on the 13-category mean: 3 of 13 categories legged, +0.028 on a legged drawing sent to
# the specialist (legs-more-v36, test split), -0.21 on another drawing sent there (route-v36)
for r in json.load(open(sys.argv[1]))["routing"]:
    print(f"threshold {r['threshold']:.2f}: expected gain {3 / 13 * 0.028 * r['recall'] - 10 / 13 * 0.21 * r['false_routes']:+.4f}")
PY
      ;;
    routed-v37)  # the routed folder OUT37/models_routed: the bundled pair, legs-more-v36's specialist as
      # mesh_predictor_legged.onnx and router-v37's router, sending a drawing to the specialist when bench + chair + table
      # pass ROUTE_THRESHOLD [0.8]: on DATA36L's table (router-v37) the threshold with the largest expected gain, 3/13 x
      # recall x 0.028 (legs-more-v36's gain on a legged drawing) - 10/13 x false routes x 0.21 (what it loses on another,
      # route-v36)
      [ -f "$OUT36/models_legs_more/mesh_predictor.onnx" ] || step export-v36-more
      rm -rf "$OUT37/models_routed"; mkdir -p "$OUT37/models_routed"
      cp assets/models/generator.onnx assets/models/mesh_predictor.onnx "$OUT37/models_routed/"
      cp "$OUT36/models_legs_more/mesh_predictor.onnx" "$OUT37/models_routed/mesh_predictor_legged.onnx"
      sketchmesh router export "$RUNS37/router" --models "$OUT37/models_routed" \
        --route "mesh_predictor_legged.onnx=$(IFS=,; echo "${LEGS[*]}")" --threshold "${ROUTE_THRESHOLD:-0.8}"
      du -b "$OUT37"/models_routed/*.onnx ;;
    eval-route-clean-v37|eval-route-side-v37|eval-route-strong-v37)  # the twenty-first pair (the files bundled before the
      # routed folder; eval-route-clean-v37 first ran with them as `--models bundled`, the same bytes) and the routed folder on every
      # test sketch of the case (DATA36A: DATA2's test split at all 48 views) as the app feeds them (canvas path, mirror
      # averaged, no refinement), into OUT37/route_{clean,side,strong}; then how the router sent them and the means
      local c=${1#eval-route-}; c=${c%-v37}
      local extra=(); [ "$c" = side ] && extra=(--elevation 0); [ "$c" = strong ] && extra=(--augment-strength 1.0)
      [ -f "$OUT36/models_twentyfirst/mesh_predictor.onnx" ] || step import-v36
      sketchmesh eval --models "$OUT36/models_twentyfirst" --models "$OUT37/models_routed" --mirror-only --data "$DATA36A" --split test \
        --views 0 --sketch-path canvas --no-retrieval "${extra[@]}" --threads 2 --quiet --out "$OUT37/route_$c" > /dev/null
      route_summary "$OUT37/route_$c/eval_models_test.json" ;;
    gallery-route-v37)  # the gallery (one test shape a category, from 30 degrees and from the side) of the twenty-first pair
      # and of the routed folders (routed2 once built), mirror averaged: OUT37/gallery_{twentyfirst,routed,routed2}{,_side}.png
      local m
      for m in twentyfirst routed routed2; do
        local folder=$OUT36/models_twentyfirst; [ "$m" != twentyfirst ] && folder=$OUT37/models_$m
        [ -f "$folder/mesh_predictor.onnx" ] || continue
        sketchmesh gallery --data "$DATA36A" --models "$folder" --mirror-average --threads 2 -o "$OUT37/gallery_$m.png"
        sketchmesh gallery --data "$DATA36A" --models "$folder" --mirror-average --elevation 0 --azimuth 90 --threads 2 \
          -o "$OUT37/gallery_${m}_side.png"
      done ;;
    latency-route-v37)  # the app's path timed (bench refine: 156 clean and 156 strong test sketches, mirror averaged, outline
      # refinement 0 and 3 steps) for the twenty-first pair, then the routed folder, one after the other (run it alone: it times)
      local m
      for m in twentyfirst routed; do
        local folder=$OUT36/models_twentyfirst; [ "$m" = routed ] && folder=$OUT37/models_routed
        sketchmesh bench refine --data "$DATA36A" --models "$folder" --max-samples "$SAMPLES2" --mirror-average \
          --steps 0 3 --no-intersections --threads 2 --quiet --out "$OUT37/latency_$m"
      done
      step router-cost-v37 ;;
    predictor-v37-legs-more2)  # the bundled specialist (predictor-v36-legs-more's run) trained on a third time as long along a
      # new cosine (the same rate, data and recipe) into RUNS37/legs_more2: does its gain still grow? V36_ITERS [3000],
      # V36_MINUTES [65] at most; resumes
      [ -f "$RUNS36/legs_more/config.json" ] || step predictor-v36-legs-more
      legs_round "$RUNS36/legs_more" "$DATA36" "$RUNS37/legs_more2" ;;
    check-legs-v37)  # predictor-v37-legs-more2's run exported as the specialist is (float16 weights, beside the bundled
      # generator; OUT37/models_legs_more2) and scored against the bundled specialist on the choice set (DATA36C, 129
      # unseen legged shapes x 4 views) through the app's engine, mirror averaged, into OUT37/check_legs
      legs_check "$OUT37" "$RUNS37/legs_more2" legs_more2 "$OUT36/models_twentyfirst" "$OUT36/models_legs_more" ;;
    routed2-v37)  # OUT37/models_routed2: the routed folder with predictor-v37-legs-more2's specialist in place of the bundled one
      [ -f "$OUT37/models_legs_more2/mesh_predictor.onnx" ] || step check-legs-v37
      rm -rf "$OUT37/models_routed2"; cp -r "$OUT37/models_routed" "$OUT37/models_routed2"
      cp "$OUT37/models_legs_more2/mesh_predictor.onnx" "$OUT37/models_routed2/mesh_predictor_legged.onnx" ;;
    eval-route2-clean-v37|eval-route2-side-v37|eval-route2-strong-v37)  # models_routed2 alone on the same drawings as
      # eval-route-*-v37 (the eval is deterministic), into OUT37/route2_<case>; its means beside that step's two columns,
      # and its paired differences from each
      local c=${1#eval-route2-}; c=${c%-v37}
      [ -f "$OUT37/models_routed2/router.onnx" ] || step routed2-v37
      route_eval "$c" "$OUT37/models_routed2" "$OUT37/route2_$c" "$OUT37/route_$c/eval_models_test.json" ;;
    router-cost-v37)  # what the router adds to each drawing, and what loading the specialist costs once (run it alone)
      python3 - "$OUT37/models_routed" <<'PY'
# 2 threads, p50 of 500 router passes (after 20 to warm up) and of 5 loads
import sys, time
import numpy as np
from engine.models import load_predictor, load_router
folder = sys.argv[1]
router = load_router(f"{folder}/router.onnx", 2)
x = np.random.default_rng(0).random((1, 3, 64, 64), dtype=np.float32)
runs = []
for _ in range(520):
    t = time.perf_counter(); router.session.run(None, {"normals": x}); runs.append(time.perf_counter() - t)
loads = []
for _ in range(5):
    t = time.perf_counter(); load_predictor(f"{folder}/mesh_predictor_legged.onnx", 2); loads.append(time.perf_counter() - t)
print(f"router pass p50 {np.median(runs[20:]) * 1e3:.3f} ms; loading the specialist p50 {np.median(loads) * 1e3:.0f} ms")
PY
      ;;
    data-v37)  # DATA37 (the router's training drawings: shapes 1300-1549 of all 13 categories, train split, 4 grid views
      # each, ~10,400 drawings) and the fifth generator's images of them and of their flipped drawings; DATA36L's images
      # (the router's validation: shapes 1200-1249); resumes
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      sketchmesh data --source procedural --first-shape 1300 --shapes-per-category 250 --views 12 \
        --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$DATA37"
      local d
      for d in "$DATA37" "$DATA36L"; do
        sketchmesh data generated "$d" --models "$OUT8/models_fifth" --name normals16 --workers 2
        sketchmesh data generated "$d" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2
      done ;;
    data-v36)  # DATA36 (training: bench, chair, table shapes 600-1199, train split, 4 grid views each), DATA36C (the
      # choice: shapes 1200-1249 of the three, as DATA72) and DATA36T (DATA2's shapes of the three, val and test); resume
      sketchmesh data --source procedural --first-shape 600 --shapes-per-category 600 --categories "${LEGS[@]}" --views 12 \
        --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$DATA36"
      sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --categories "${LEGS[@]}" --views 12 \
        --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$DATA36C"
      sketchmesh data --source procedural --shapes-per-category 100 --categories "${LEGS[@]}" --views 12 \
        --elevations 0 15 30 45 --splits val test --workers 2 --out "$DATA36T" ;;
    generated-v36|generated-mirror-v36)  # the fifth generator's images of DATA36's drawings and of their flipped drawings
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      local name=(--name normals16); [ "${1#generated-mirror-}" != "$1" ] && name=(--name normals16_mirror --mirror)
      sketchmesh data generated "$DATA36" --models "$OUT8/models_fifth" "${name[@]}" --workers 2 ;;
    import-v36)  # the twenty-first pair (git TWENTYFIRST [2a2eadb]) into OUT36/models_twentyfirst, its predictor back as a
      # run (RUNS36/twentyfirst/predictor; batch norms calibrated on DATA36's generated images)
      models_from_git "${TWENTYFIRST:-2a2eadb}" "$OUT36/models_twentyfirst"
      [ -f "$RUNS36/twentyfirst/predictor/config.json" ] || \
        sketchmesh import-models "$OUT36/models_twentyfirst" --out "$RUNS36/twentyfirst" --only predictor --data "$DATA36" --threads 2 ;;
    predictor-v36-legs)  # the twenty-first's predictor trained on bench, chair and table alone (DATA36) by the CPU recipe
      # (recipe20) at V36_LR [2e-4] along a new cosine into RUNS36/legs: V36_ITERS [3000], V36_MINUTES [65] at most;
      # resumes
      [ -f "$DATA36/.cache/generated/normals16_mirror/info.json" ] || { echo "$1 reads $DATA36: run data-v36 generated-v36 generated-mirror-v36 first" >&2; exit 1; }
      [ -f "$RUNS36/twentyfirst/predictor/config.json" ] || step import-v36
      legs_round "$RUNS36/twentyfirst/predictor" "$DATA36" "$RUNS36/legs" ;;
    predictor-v36-legs-more)  # predictor-v36-legs's run trained on as long again along a new cosine (the same rate, data
      # and recipe) into RUNS36/legs_more: does the specialist's gain grow with its samples? V36_ITERS [3000],
      # V36_MINUTES [65] at most; resumes
      [ -f "$RUNS36/legs/config.json" ] || step predictor-v36-legs
      legs_round "$RUNS36/legs" "$DATA36" "$RUNS36/legs_more" ;;
    export-v36|export-v36-more)  # predictor-v36-legs's (-more: predictor-v36-legs-more's) run with float16-stored weights
      # beside the bundled generator: OUT36/models_legs (models_legs_more)
      local run=legs; [ "$1" = export-v36-more ] && run=legs_more
      rm -rf "$OUT36/models_$run"
      sketchmesh export "$RUNS36/$run" -o "$OUT36/models_$run" --quantize fp16
      cp "$OUT36/models_twentyfirst/generator.onnx" "$OUT36/models_$run/" ;;
    check-legs-v36|eval-legs-v36|eval-legs-side-v36)  # the twenty-first pair and the specialist (and its continuation,
      # once export-v36-more has run) through the app's engine (`eval --models`, plain and +mirror): check-legs on
      # DATA36C's 4 views of each shape, eval-legs on DATA36T's test split at 12 of each shape's 48 views,
      # eval-legs-side at its 12 side views (0 degrees); into OUT36/<step>
      local data=$DATA36T split=test views=(--views 12) more=()
      [ "$1" = check-legs-v36 ] && { data=$DATA36C; split=train; views=(--views 4); }
      [ "$1" = eval-legs-side-v36 ] && views=(--elevation 0 --views 12)
      [ -f "$OUT36/models_legs_more/mesh_predictor.onnx" ] && more=(--models "$OUT36/models_legs_more")
      sketchmesh eval --models "$OUT36/models_twentyfirst" --models "$OUT36/models_legs" "${more[@]}" --data "$data" \
        --split "$split" "${views[@]}" --no-retrieval --mirror-average --threads 2 --out "$OUT36/${1%-v36}" ;;
    gallery-legs-v36)  # three test shapes of each legged category, the twenty-first pair and the specialist (and its
      # continuation once exported), mirror averaged: OUT36/gallery_<models>.png
      local m
      for m in twentyfirst legs legs_more; do
        [ -f "$OUT36/models_$m/mesh_predictor.onnx" ] || continue
        sketchmesh gallery --data "$DATA36T" --models "$OUT36/models_$m" --per-category 3 --mirror-average --threads 2 \
          -o "$OUT36/gallery_$m.png"
      done ;;
    route-v36)  # the router a specialist needs, measured: the category of the nearest training drawing (the retrieval
      # floor of `eval --models`, searched among DATA36L [data/lib1200v4]: 50 unseen shapes of every category at 4 grid
      # views) as the router, on DATA2's 139 test shapes of all 13 categories (DATA36A [data/test100e4], the test split
      # at 48 views) at 4 views each. One eval of the twenty-first pair and predictor-v36-legs-more's specialist through
      # the app's engine, mirror averaged, with that retrieval, into OUT36/route; the python below counts how often the
      # router says legged (bench, chair, table) exactly when the drawing is, then scores each drawing by the specialist
      # where the router sends it (and, as a ceiling, where the drawing truly is legged): means over the 13 categories
      [ -f "$OUT36/models_legs_more/mesh_predictor.onnx" ] || step export-v36-more
      sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --views 12 --elevations 0 15 30 45 \
        --views-per-shape 4 --splits train --workers 2 --out "$DATA36L"
      sketchmesh data --source procedural --shapes-per-category 100 --views 12 --elevations 0 15 30 45 --splits test \
        --workers 2 --out "$DATA36A"
      sketchmesh eval --models "$OUT36/models_twentyfirst" --models "$OUT36/models_legs_more" --data "$DATA36A" --split test \
        --retrieval-data "$DATA36L" --mirror-average --threads 2 --out "$OUT36/route"
      python3 - "$OUT36/route/eval_models_test.json" "${LEGS[@]}" <<'PY'
import json, sys
from collections import defaultdict
rows = json.load(open(sys.argv[1]))["rows"]
legs = set(sys.argv[2:])
views = [(r["category"], v["retrieved"].split("/")[0], v) for r in rows for v in r["per_view"]]
n = len(views)
legged = sum(cat in legs for cat, _, _ in views)
print(f"{n} test drawings ({legged} legged): category of the nearest training drawing right for "
      f"{sum(cat == rc for cat, rc, _ in views) / n:.3f}; legged-or-not right for "
      f"{sum((cat in legs) == (rc in legs) for cat, rc, _ in views) / n:.3f}; "
      f"{sum(rc in legs for _, rc, _ in views)} sent to the specialist")
base, spec = "models_twentyfirst +mirror", "models_legs_more +mirror"
ways = {"twenty-first": lambda cat, rc: base, "routed": lambda cat, rc: spec if rc in legs else base,
        "routed perfectly": lambda cat, rc: spec if cat in legs else base}
for name, pick in ways.items():
    per_cat = defaultdict(list)
    for r in rows:
        ious = [v["iou"][pick(r["category"], v["retrieved"].split("/")[0])] for v in r["per_view"]]
        per_cat[r["category"]].append(sum(ious) / len(ious))
    cats = {c: sum(x) / len(x) for c, x in per_cat.items()}
    print(f"{name}: mean of {len(cats)} categories {sum(cats.values()) / len(cats):.4f} (legged "
          f"{sum(cats[c] for c in legs) / len(legs):.4f}); " + ", ".join(f"{c} {v:.3f}" for c, v in sorted(cats.items())))
PY
      ;;
    eval-views-v35)  # variants-views-v35's two predictors scored as eval-data-v35 scores its (DATA100's test drawings,
      # silhouette-only first), into OUT35/eval_views
      drawings_eval "$DATA100" no "$OUT35/variants_views" "$OUT35/modelsviews" "$OUT35/eval_views" variants-views-v35 \
        silhouette-only-k1 full-interior-k1 ;;
    compare-single-v34)  # overfit-v31 and overfit-sil-v34 (four views) beside the one-view runs, full and silhouette-only
      # (seconds), into OUT34/compare_single with the car's rows; those rows to docs/
      sketchmesh bench overfit-compare "full-4views=$OUT31/overfit" "silhouette-4views=$OUT34/overfit_sil" \
        "full-1view=$OUT34/overfit_single" "silhouette-1view=$OUT34/overfit_single_sil" --out "$OUT34/compare_single" \
        --shape car_00000
      cp "$OUT34/compare_single/compare_car_00000.png" docs/overfit_single_car.png ;;
    compare-interior-v34)  # overfit-v31 (the paper's normal term) beside overfit-interior-v34 (off the outline) and
      # overfit-sil-v34 (silhouette-only) (seconds), into OUT34/compare_normal with the table's and the car's rows; the
      # plot and both rows to docs/
      sketchmesh bench overfit-compare "full-paper=$OUT31/overfit" "full-interior=$OUT34/overfit_interior" \
        "silhouette-only=$OUT34/overfit_sil" --out "$OUT34/compare_normal" --shape table_00000 --shape car_00000
      cp "$OUT34/compare_normal/compare.png" docs/overfit_normal.png
      cp "$OUT34/compare_normal/compare_table_00000.png" docs/overfit_normal_table.png
      cp "$OUT34/compare_normal/compare_car_00000.png" docs/overfit_normal_car.png ;;
    soup-v30)  # a weight average ("soup") of the twenty-first predictor and its three CPU passes on DATA70 (predictor-v27's
      # v27_fresh, -low's v27_low, -b512's v27_b512; run them first), equal weights, batch norms set again on 1,024 of
      # DATA70's generated inputs (`sketchmesh average`), into RUNS30/soup4; soup3 leaves the twenty-first out, soup5 adds
      # control-v27's silhouette-only pass (v27_low_sil); seconds each
      local r
      for r in v27_fresh v27_low v27_b512 v27_low_sil; do
        [ -f "$RUNS27/$r/config.json" ] || { echo "soup-v30 averages $RUNS27/$r: run predictor-v27, predictor-v27-low, predictor-v27-b512 and control-v27 first" >&2; exit 1; }
      done
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
      local four=("$RUNS27/twentyfirst/predictor" "$RUNS27/v27_low" "$RUNS27/v27_b512" "$RUNS27/v27_fresh")
      rm -rf "$RUNS30/soup4" "$RUNS30/soup3" "$RUNS30/soup5"
      sketchmesh average "${four[@]}" --out "$RUNS30/soup4" --data "$DATA70" --threads 2
      sketchmesh average "${four[@]:1}" --out "$RUNS30/soup3" --data "$DATA70" --threads 2
      sketchmesh average "${four[@]}" "$RUNS27/v27_low_sil" --out "$RUNS30/soup5" --data "$DATA70" --threads 2 ;;
    check-soup-v30|check-soup-strong-v30|check-soup-side-v30)  # the soups (soup-v30) against the twenty-first on DATA72
      # (check-*-v27's 520 sketches a case), plain and +mirror, into OUT30/check_*: soup4 everywhere, soup3 and soup5
      # on clean sketches only (3 min a case, 6 with the two)
      [ -f "$RUNS30/soup4/config.json" ] || step soup-v30
      eval_case "${1/check-soup-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      if [ "$1" = check-soup-v30 ]; then
        check72 "$OUT30/check_${EVAL_NAME#eval_}" "$RUNS30/soup4" "$RUNS30/soup3" "$RUNS30/soup5"
      else
        check72 "$OUT30/check_${EVAL_NAME#eval_}" "$RUNS30/soup4"
      fi ;;
    eval-soup-v30|eval-soup-strong-v30|eval-soup-side-v30)  # the twenty-first against soup4 on every test sketch, plain
      # and +mirror: clean and side views from the stored rasters (as eval-full-*-v27; the canvas path gives the same
      # clean figure), strong augmentation through the canvas (as eval-canvas-strong-v29); 30 min for clean and
      # strong, 8 for side; into OUT30/full/eval_*
      [ -f "$RUNS30/soup4/config.json" ] || step soup-v30
      eval_case "${1/eval-soup-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      [ "$1" = eval-soup-strong-v30 ] && EVAL_EXTRA+=(--sketch-path canvas)
      SAMPLES2=0 eval_against test "$OUT30/full/$EVAL_NAME" "$RUNS27/twentyfirst/predictor" "$RUNS30/soup4" ;;
    check-scale-v29|check-scale-strong-v29)  # a calibration probe: the twenty-first's meshes scaled by 0.98 about their
      # bounding-box centres before scoring (`eval --mesh-scale`), on check-*-v27's DATA72 sketches (520 a case), plain
      # and +mirror, into OUT29/check_scale_*: check-v27's twenty-first columns are the same sketches unscaled
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || step import-v27
      eval_case "${1/check-scale-/eval-}"; EVAL_EXTRA+=(--mirror-average --mesh-scale "${MESH_SCALE:-0.98}")
      check72 "$OUT29/check_scale_${EVAL_NAME#eval_}" ;;
    data-v27-check)  # DATA72 [data/check1200v4]: a second validation set no run has trained on or been chosen by: shapes
      # 1200-1249 of each category (`data --first-shape 1200`), their train split, 4 of the 48 grid views each; about 2 min
      sketchmesh data --source procedural --first-shape 1200 --shapes-per-category 50 --views 12 --elevations 0 15 30 45 \
        --views-per-shape 4 --splits train --workers 2 --out "$DATA72" ;;
    joint-pilot-v28)  # the fine-tune's rate and weight, six short runs (about 2 min per 200 iterations) against the
      # twenty-first pair on 260 strongly augmented sketches of DATA72, plain and +mirror: RMSProp at the generator's own
      # 5e-5 (weights 1, 30; 200 it) and at 5e-6 (weight 30, 200 it; weight 1000, the mesh loss alone, and weight 1000
      # with the generator's dropout off, as it runs in the app: 500 it)
      # into RUNS28/pilot_*, OUT28/pilot_5e-5 and OUT28/pilot_5e-6
      joint28 "$RUNS28/pilot_fast_w1" 200 5e-5 1
      joint28 "$RUNS28/pilot_fast_w30" 200 5e-5 30
      joint28 "$RUNS28/pilot_w30" 200 5e-6 30
      joint28 "$RUNS28/pilot_w1000" 500 5e-6 1000
      joint28 "$RUNS28/pilot_mesh" 500 5e-6 1 --lambda-g 0 --lambda-l 0
      joint28 "$RUNS28/pilot_nodrop" 500 5e-6 1000 --no-generator-dropout
      EVAL_EXTRA=(--mirror-average --augment-strength 1.0 --quiet)
      CHECK_SAMPLES=260 check72 "$OUT28/pilot_5e-5" "$RUNS28"/pilot_fast_w{1,30}
      CHECK_SAMPLES=260 check72 "$OUT28/pilot_5e-6" "$RUNS28"/pilot_{w30,w1000,mesh,nodrop} ;;
    joint-v28)  # the fine-tune: rate 5e-6, weight 1000 (joint-pilot-v28), V28_ITERS [4800] iterations (19,200 sketches,
      # 0.77 of DATA70's 25,060 views), V28_MINUTES [50] at most, into RUNS28/joint; resumes
      joint28 "$RUNS28/joint" "${V28_ITERS:-4800}" 5e-6 1000 --max-minutes "${V28_MINUTES:-50}" ;;
    generated-v28-strong|generated-mirror-v28-strong)  # generated-v27's images drawn from DATA70's sketches at the strong
      # augmentation the strong case is scored at (1.0; the predictor's generated sets so far used 0.5): normals16_s1 and
      # normals16_s1_mirror, 8 min each on 2 cores; resume
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      local name=(--name normals16_s1); [ "${1#generated-mirror-}" != "$1" ] && name=(--name normals16_s1_mirror --mirror)
      sketchmesh data generated "$DATA70" --models "$OUT8/models_fifth" "${name[@]}" --augment-strength 1.0 --workers 2 ;;
    predictor-v28-strong)  # predictor-v27-low (the twenty-first on DATA70 at 2e-5, 1,300 iterations) on the generator's
      # images of strongly augmented drawings instead (generated-*-v28-strong), into RUNS28/strong_inputs
      # (V28_STRONG_MINUTES [25] at most; resumes)
      v27_start "$1"
      [ -f "$DATA70/.cache/generated/normals16_s1_mirror/info.json" ] || { echo "$1 reads normals16_s1: run generated-v28-strong generated-mirror-v28-strong first" >&2; exit 1; }
      TRAIN_INPUTS=normals16_s1 RECIPE_LR=${V27_LOW_LR:-2e-5} DATA20=$DATA70 recipe20 "$RUNS27/twentyfirst/predictor" \
        "$RUNS28/strong_inputs" "${V27_LOW_ITERS:-1300}" "${V28_STRONG_MINUTES:-25}" 2 ;;
    check-v28-strong|check-strong-v28-strong|check-side-v28-strong)  # predictor-v28-strong's run against the twenty-first
      # and predictor-v27-low (the same pass on the 0.5 images) on DATA72, as check-*-v28, into OUT28/strong_inputs_*
      local c=${1%-strong}; eval_case "${c/check-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      check72 "$OUT28/strong_inputs_${EVAL_NAME#eval_}" "$RUNS28/strong_inputs" "$RUNS27/v27_low" ;;
    logs-v28)  # joint-v28's run: the losses over its first and last iterations
      log_summary "$RUNS28" joint ;;
    check-v28|check-strong-v28|check-side-v28)  # the fine-tuned pair (joint-v28's run: its own generator) against the
      # twenty-first pair on DATA72 (CHECK_SAMPLES [520] sketches per case), plain and +mirror, into OUT28/check_*
      eval_case "${1/check-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      check72 "$OUT28/check_${EVAL_NAME#eval_}" "$RUNS28/joint" ;;
    check-v27|check-strong-v27|check-side-v27)  # is the twenty-first's lead over the CPU passes the validation split's
      # choice? The twenty-first against predictor-v27's, -low's and -b512's runs on DATA72 (CHECK_SAMPLES [520] sketches
      # per case), plain and +mirror, into OUT27/check_*
      eval_case "${1/check-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      check72 "$OUT27/check_${EVAL_NAME#eval_}" "$RUNS27/v27_low" "$RUNS27/v27_b512" "$RUNS27/v27_fresh" ;;
    generated-v27|generated-mirror-v27)  # generated-v26's images (the same generator and settings) on DATA70; resume
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      local name=(--name normals16); [ "${1#generated-mirror-}" != "$1" ] && name=(--name normals16_mirror --mirror)
      sketchmesh data generated "$DATA70" --models "$OUT8/models_fifth" "${name[@]}" --workers 2 ;;
    import-v27)  # the twenty-first pair (git TWENTYFIRST [2a2eadb]) into OUT27/models_twentyfirst, its predictor back
      # as a run (RUNS27/twentyfirst/predictor; batch norms calibrated on DATA70's generated images), and the fifth
      # pair's runs (import-v8: eval_against's generator run)
      [ -f "$RUNS8/fifth/generator/config.json" ] || step import-v8
      models_from_git "${TWENTYFIRST:-2a2eadb}" "$OUT27/models_twentyfirst"
      [ -f "$RUNS27/twentyfirst/predictor/config.json" ] || \
        sketchmesh import-models "$OUT27/models_twentyfirst" --out "$RUNS27/twentyfirst" --only predictor --data "$DATA70" --threads 2 ;;
    predictor-v27)  # the twenty-first trained on DATA70 by the CPU recipe (recipe20) along a new cosine into
      # RUNS27/v27_fresh: V27_ITERS [3000], V27_MINUTES [50] at most, two threads; resumes
      v27_start "$1"
      DATA20=$DATA70 recipe20 "$RUNS27/twentyfirst/predictor" "$RUNS27/v27_fresh" "${V27_ITERS:-3000}" "${V27_MINUTES:-50}" 2 ;;
    predictor-v27-low)  # predictor-v27 at a fifth of its peak rate (V27_LOW_LR [2e-5]): the CPU recipe's 1e-4 at batch 32
      # lost 0.015 on validation against the twenty-first, whose last stage ran at batch 512 (val-*-v27); into
      # RUNS27/v27_low, V27_LOW_ITERS [1300], V27_LOW_MINUTES [25] at most; resumes
      v27_start "$1"
      RECIPE_LR=${V27_LOW_LR:-2e-5} DATA20=$DATA70 recipe20 "$RUNS27/twentyfirst/predictor" "$RUNS27/v27_low" \
        "${V27_LOW_ITERS:-1300}" "${V27_LOW_MINUTES:-25}" 2 ;;
    predictor-v27-b512)  # predictor-v27 at the GPU stage's batch (512) and a rate between its two calls' (V27_B512_LR
      # [1e-4], 10 warm-up steps): is it the batch-32 steps that move the twenty-first off its optimum? Into
      # RUNS27/v27_b512, V27_B512_ITERS [100], V27_B512_MINUTES [25] at most; resumes
      v27_start "$1"
      RECIPE_LR=${V27_B512_LR:-1e-4} RECIPE_EXTRA="--batch 512 --lr-warmup 10" DATA20=$DATA70 recipe20 \
        "$RUNS27/twentyfirst/predictor" "$RUNS27/v27_b512" "${V27_B512_ITERS:-100}" "${V27_B512_MINUTES:-25}" 2 ;;
    control-v27)  # predictor-v27-low's silhouette-only control: the same start (the twenty-first), data (DATA70), recipe,
      # rate (V27_LOW_LR [2e-5]) and V27_LOW_ITERS [1300] iterations with the normal weight 0, into RUNS27/v27_low_sil
      # (V27_CONTROL_MINUTES [40] at most, so a busy machine still ends at the same iteration; resumes)
      v27_start "$1"
      RECIPE_LR=${V27_LOW_LR:-2e-5} DATA20=$DATA70 recipe20 "$RUNS27/twentyfirst/predictor" "$RUNS27/v27_low_sil" \
        "${V27_LOW_ITERS:-1300}" "${V27_CONTROL_MINUTES:-40}" 2 0 ;;
    eval-control-v27|eval-control-strong-v27|eval-control-side-v27)  # full minus silhouette-only over the twenty-first's
      # continuation: predictor-v27-low's run against control-v27's, plain and +mirror, test split (OUT27/control/eval_*)
      local c=${1/control-/}; eval_case "$c"; EVAL_EXTRA+=(--mirror-average)
      eval_against test "$OUT27/control/$EVAL_NAME" "$RUNS27/v27_low" "$RUNS27/v27_low_sil" ;;
    val-v27-b512|val-strong-v27-b512|val-side-v27-b512)  # predictor-v27-b512's run against predictor-v27-low's and
      # their start, plain and +mirror, validation split (OUT27/val_b512_*)
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT27/val_b512_${EVAL_NAME#eval_}" "$RUNS27/v27_b512" "$RUNS27/v27_low" "$RUNS27/twentyfirst/predictor" ;;
    val-v27-low|val-strong-v27-low|val-side-v27-low)  # predictor-v27-low's run against predictor-v27's and their start,
      # plain and +mirror, validation split (OUT27/val_low_*)
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT27/val_low_${EVAL_NAME#eval_}" "$RUNS27/v27_low" "$RUNS27/v27_fresh" "$RUNS27/twentyfirst/predictor" ;;
    logs-v27)  # predictor-v27's, predictor-v27-low's and predictor-v27-b512's runs: the losses over their first and last iterations
      log_summary "$RUNS27" v27_fresh v27_low v27_b512 ;;
    val-v27|val-strong-v27|val-side-v27)  # predictor-v27's run against its start, the twenty-first, plain and +mirror,
      # validation split (OUT27/val_*)
      eval_case "${1/val-/eval-}"; EVAL_EXTRA+=(--mirror-average)
      eval_against val "$OUT27/val_${EVAL_NAME#eval_}" "$RUNS27/v27_fresh" "$RUNS27/twentyfirst/predictor" ;;
    session-nice)  # is the app's slowness under load its own thread priorities? play_session with the inference
      # worker's and the render thread's nice values (SKETCHMESH_WORKER_NICE:SKETCHMESH_RENDER_NICE) at each of NICE_PAIRS
      # ["10:5 0:5 0:0"; 10:5 the defaults before 2026-11-27], idle and under session-load's busy loops, in turn twice
      # (A B C, A B C), into OUT27/session_nice, then session_table (run it alone: it times)
      local k pair w r
      mkdir -p "$OUT27/session_nice"
      for k in 1 2; do
        for pair in ${NICE_PAIRS:-10:5 0:5 0:0}; do
          w=${pair%:*}; r=${pair#*:}
          SKETCHMESH_WORKER_NICE=$w SKETCHMESH_RENDER_NICE=$r play_session "$OUT27/session_nice/w${w}_r${r}_idle_$k.json"
          busy_start
          SKETCHMESH_WORKER_NICE=$w SKETCHMESH_RENDER_NICE=$r play_session "$OUT27/session_nice/w${w}_r${r}_load_$k.json"
          busy_stop
        done
      done
      session_table "$OUT27/session_nice" ;;
    mirror-v13)  # mirror averaging, validation split first, then the test split, its cost and the pictures
      for s in val-mirror-v13 val-strong-mirror-v13 val-side-mirror-v13 val-gt-mirror-v13 val624-mirror-v13 \
               eval-mirror-v13 eval-strong-mirror-v13 eval-side-mirror-v13 eval-gt-mirror-v13 cost-v13 compare-v13 \
               tradeoff-v13 refine-v13 gallery-v13 docs-v13; do
        step "$s"
      done ;;
    val-gpu-v11)  # the tenth's GPU stage on the validation split's true normal images: its end (g11_b512b) and the
      # first call's run (g11_b512) against the ninth predictor it started from
      sketchmesh eval "$RUNS11/g11_b512b" --data "$DATA2" --split val --gt-normals --baseline-run "$RUNS10/v10_more" \
        --baseline-run "$RUNS11/g11_b512" --no-retrieval --max-samples "$SAMPLES2" --threads 2 --out "$OUT11/val_gt_gpu" ;;
    predictor-v11)  # two candidates for the tenth predictor at equal CPU time, side by side on one thread each, with the
      # seventh's recipe (Adam 2e-4 cosine over V11_ITERS [10000], V11_MINUTES [52] at most; resumes): from the
      # GPU-continued ninth (v11_gpu: RUNS11/g11_b512b, fetch-gpu-v11) and from the ninth as shipped (v11_cpu: RUNS10/v10_more)
      [ -f "$RUNS11/g11_b512b/config.json" ] || { echo "predictor-v11 starts from $RUNS11/g11_b512b: run training/gpu_predictor.sh on a GPU, then fetch-gpu-v11" >&2; exit 1; }
      [ -f "$RUNS10/v10_more/config.json" ] || { echo "predictor-v11 compares against $RUNS10/v10_more: run all-v10-more first" >&2; exit 1; }
      finetune_pair "$RUNS11/g11_b512b" "$RUNS10/v10_more" "$RUNS11/v11" "${V11_ITERS:-10000}" "${V11_MINUTES:-52}" ;;
    val-v11|val-strong-v11|val-side-v11|val-gt-v11)  # predictor-v11's two runs against the ninth, validation split
      local c=${1/val-/eval-}; eval_case "$c"
      eval_against val "$OUT11/val_${EVAL_NAME#eval_}" "$RUNS11/v11_gpu" "$RUNS11/v11_cpu" "$RUNS10/v10_more" ;;
    eval-v11|eval-strong-v11|eval-side-v11|eval-gt-v11)  # the same on the test split, into OUT11/final
      eval_case "$1"
      eval_against test "$OUT11/final/$EVAL_NAME" "$RUNS11/v11_gpu" "$RUNS11/v11_cpu" "$RUNS10/v10_more" ;;
    fit-v11|fit-gt-v11)  # how well the v11 runs and the ninth fit what they trained on: the training split, from clean
      # sketches (fit-v11) or true normal images (fit-gt-v11), against the validation split's figures (val-*-v11)
      [ "$1" = fit-gt-v11 ] && EVAL_EXTRA=(--gt-normals) || EVAL_EXTRA=()
      eval_against train "$OUT11/${1%-v11}_train" "$RUNS11/v11_gpu" "$RUNS11/v11_cpu" "$RUNS10/v10_more" ;;
    logs-v11)  # the v11 runs' training logs: rate and wall time, the silhouette term and normal error
      log_summary "$RUNS11" g11_b512 g11_b512b v11_gpu v11_cpu ;;
    export-v11)  # the chosen predictor (PRED11 [v11_gpu]) as float32 and int8, beside the generator file
      export_pair "$RUNS11/${PRED11:-v11_gpu}" "$OUT11/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v11)  # error against run time in the app's engine (run it alone: it times)
      tradeoff_of "w16-v11" "$OUT11/final" ;;
    compare-v11)  # the app's ONNX path: the nine bundled pairs so far (from git), the tenth, retrieval and the template
      compare_pairs "$OUT11" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f bd55d3c 6e6475c 43b2613 ;;
    predictor-v11-more)  # the tenth predictor (PRED11 [v11_gpu]) trained on alone on two threads with the same recipe
      # (V11M_ITERS [9000], V11M_MINUTES [32] at most; resumes), then checked against it on the validation split
      train7 "$RUNS11/${PRED11:-v11_gpu}" "$RUNS11/v11_more" "${V11M_ITERS:-9000}" "${V11M_MINUTES:-32}" 2 ;;
    val-v11-more|val-strong-v11-more|val-side-v11-more|val-gt-v11-more)  # v11_more against the tenth, validation split
      local c=${1/val-/eval-}; eval_case "${c%-more}"
      eval_against val "$OUT11/more/val_${EVAL_NAME#eval_}" "$RUNS11/v11_more" "$RUNS11/${PRED11:-v11_gpu}" ;;
    eval-v11-more|eval-strong-v11-more|eval-side-v11-more|eval-gt-v11-more)  # the same on the test split
      eval_case "${1%-more}"
      eval_against test "$OUT11/more/final/$EVAL_NAME" "$RUNS11/v11_more" "$RUNS11/${PRED11:-v11_gpu}" ;;
    export-v11-more)  # v11_more as float32 and int8, beside the generator file
      export_pair "$RUNS11/v11_more" "$OUT11/more/final" "$OUT8/models_fifth/generator.onnx" ;;
    tradeoff-v11-more)  # error against run time in the app's engine (run it alone: it times)
      tradeoff_of "w16-v11-more" "$OUT11/more/final" ;;
    compare-v11-more)  # the app's ONNX path: the nine bundled pairs before the tenth (from git), v11_more, retrieval, the template
      compare_pairs "$OUT11/more" 2e5204b cc51aaf 0c5ab8e 3a1ec5a 5b01fa5 d5aca6f bd55d3c 6e6475c 43b2613 ;;
    all-v11-more)  # the tenth predictor trained on (after fresh-v11): trained, checked, measured, shipped
      SHIP_MODELS=$OUT11/more/final/models_fp32; SHIP_OUT=$OUT11/more/final; CENTRES=()
      for s in predictor-v11-more val-v11-more val-strong-v11-more val-side-v11-more val-gt-v11-more eval-v11-more \
               eval-strong-v11-more eval-side-v11-more eval-gt-v11-more export-v11-more tradeoff-v11-more gallery-v2 \
               compare-v11-more ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    control-v10-more)  # the ninth predictor's silhouette-only control: predictor-v10-more's run (the same start, v10_gpu,
      # mirrored items, schedule and 11,000 iterations) with the normal weight 0, alone on two threads
      # (V10MC_MINUTES [45] at most; resumes)
      train7 "$RUNS10/v10_gpu" "$RUNS10/v10_silhouette" "${V10M_ITERS:-11000}" "${V10MC_MINUTES:-45}" 2 0 ;;
    eval-control-v10-more|eval-control-strong-v10-more|eval-control-side-v10-more|eval-control-gt-v10-more)  # full
      # minus silhouette-only for the ninth pair: v10_more against control-v10-more on the test split
      local c=${1/control-/}; eval_case "${c%-more}"
      eval_against test "$OUT10/more/control/$EVAL_NAME" "$RUNS10/v10_more" "$RUNS10/v10_silhouette" ;;
    logs-control-v10-more)  # the ninth's run and its silhouette-only control: rate, silhouette term, normal error
      log_summary "$RUNS10" v10_more v10_silhouette ;;
    fresh-v11)  # the tenth candidate (after fresh-v10 and all-v10-more, with gpu_predictor.sh's two calls in GPU_FILES1
      # and GPU_FILES2)
      GPU_FILES=${GPU_FILES1:?set GPU_FILES1 and GPU_FILES2 to the folders of the two calls} step fetch-gpu-v11
      GPU_FILES=${GPU_FILES2:?set GPU_FILES2} step fetch-gpu-v11
      for s in val-gpu-v11 predictor-v11 val-v11 val-strong-v11 val-side-v11 val-gt-v11 eval-v11 eval-strong-v11 \
               eval-side-v11 eval-gt-v11 logs-v11; do step "$s"; done ;;
    all-v11)  # the tenth bundled models (after fresh-v11): exported, timed, shipped
      SHIP_MODELS=$OUT11/final/models_fp32; SHIP_OUT=$OUT11/final; CENTRES=()
      for s in export-v11 tradeoff-v11 gallery-v2 compare-v11 ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    fresh-v8)  # the sixth candidate from a fresh clone: data, the fifth pair imported, trained on, measured
      [ -f "$DATA2/manifest.json" ] || step data-v2
      for s in models-fifth-v8 generated-v8 import-v8 predictor-v8 mirror-check-v8 val-v8 eval-v8 eval-strong-v8 \
               eval-side-v8 eval-gt-v8 predictor-v8-more val-v8-more logs-v8; do step "$s"; done ;;
    all-v8)  # the sixth bundled models (after fresh-v8 and predictor-v8-more val-v8-more): measured, exported, timed, shipped
      SHIP_MODELS=$OUT8/final/models_int8; SHIP_OUT=$OUT8/final; CENTRES=()
      for s in eval-v8b eval-strong-v8b eval-side-v8b eval-gt-v8b export-v8 tradeoff-v8 gallery-v2 compare-v8 ship-v2 \
               refine-v2 docs-v2; do step "$s"; done ;;
    fresh-v9)  # the seventh candidate (after fresh-v8 and predictor-v8-more): mirrored inputs, trained, chosen, measured
      for s in generated-mirror-v9 predictor-v9 val-v9 val-strong-v9 val-side-v9 val-gt-v9 eval-v9 eval-strong-v9 eval-side-v9 eval-gt-v9 logs-v9; do
        step "$s"
      done ;;
    all-v9)  # the seventh bundled models (after fresh-v9): exported, timed, shipped; then its silhouette-only control
      SHIP_MODELS=$OUT9/final/models_fp32; SHIP_OUT=$OUT9/final; CENTRES=()
      for s in export-v9 tradeoff-v9 gallery-v2 compare-v9 ship-v2 refine-v2 docs-v2; do step "$s"; done
      for s in control-v9 eval-control-v9 eval-control-strong-v9 eval-control-side-v9 eval-control-gt-v9; do step "$s"; done ;;
    fresh-v10)  # the eighth candidate (after fresh-v9, with what gpu_predictor.sh brought back in GPU_FILES)
      for s in fetch-gpu-v10 val-gpu-v10 predictor-v10 val-v10 val-strong-v10 val-side-v10 val-gt-v10 eval-v10 \
               eval-strong-v10 eval-side-v10 eval-gt-v10 logs-v10; do step "$s"; done ;;
    all-v10)  # the eighth bundled models (after fresh-v10): exported, timed, shipped
      SHIP_MODELS=$OUT10/final/models_fp32; SHIP_OUT=$OUT10/final; CENTRES=()
      for s in export-v10 tradeoff-v10 gallery-v2 compare-v10 ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    all-v10-more)  # the eighth predictor trained on (after fresh-v10 all-v10): trained, checked, measured, shipped
      SHIP_MODELS=$OUT10/more/final/models_fp32; SHIP_OUT=$OUT10/more/final; CENTRES=()
      for s in predictor-v10-more val-v10-more val-strong-v10-more val-side-v10-more val-gt-v10-more eval-v10-more \
               eval-strong-v10-more eval-side-v10-more eval-gt-v10-more export-v10-more tradeoff-v10-more gallery-v2 \
               compare-v10-more ship-v2 refine-v2 docs-v2; do step "$s"; done ;;
    fit-chair-v57)  # the direct fit (bench fit, 8 views, 1,000 iterations, damping 4) of the first FIT57_SHAPES [8]
      # training shapes of FIT57_CATEGORIES [chair] at each "RESOLUTION LEVEL" of FIT57_CONFIGS [64 3;128 3;64 4;128 4]
      # (silhouette and normal images of RESOLUTION pixels, the icosphere at LEVEL: 642 vertices at 3, 2,562 at 4), with
      # the supports each fit stands on, into OUT57/fit_<categories>_r<RESOLUTION>_l<LEVEL>.json and its meshes
      # (one thread a fit; two configurations at a time on two cores)
      mkdir -p "$OUT57"
      local cfg r l tag pids=() cats=${FIT57_CATEGORIES:-chair} cfgs
      IFS=';' read -ra cfgs <<< "${FIT57_CONFIGS:-64 3;128 3;64 4;128 4}"
      for cfg in "${cfgs[@]}"; do
        read -r r l <<< "$cfg"
        tag=${cats//,/_}_r${r}_l$l
        sketchmesh bench fit --procedural "${FIT57_SHAPES:-8}" --categories "$cats" --resolution "$r" --level "$l" \
          --meshes "$OUT57/meshes_$tag" --json "$OUT57/fit_$tag.json" > "$OUT57/fit_$tag.txt" 2>&1 &
        pids+=($!)
        if [ ${#pids[@]} -ge 2 ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
      done
      for r in "${pids[@]}"; do wait "$r"; done
      grep -h -A30 '^fit:' "$OUT57"/fit_"${cats//,/_}"_r*.txt ;;
    fit-test-v57)  # the direct fit (as fit-chair-v57 at 64 3) of every test bench, chair and table of DATA36A (the
      # procedural library's test shapes below index 100: as many a category as DATA36A holds) into
      # OUT57/fit_test_<category>.json and its meshes (one thread a fit, two categories at a time; about 20 min)
      mkdir -p "$OUT57"
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      local c n pids=()
      for c in "${LEGS[@]}"; do
        n=$(python3 -c "import json,sys; print(sum(s['category'] == sys.argv[2] for s in json.load(open(sys.argv[1]))['shapes']))" \
          "$DATA36A/manifest.json" "$c")
        sketchmesh bench fit --procedural "$n" --split test --categories "$c" --meshes "$OUT57/meshes_test" \
          --json "$OUT57/fit_test_$c.json" > "$OUT57/fit_test_$c.txt" 2>&1 &
        pids+=($!)
        if [ ${#pids[@]} -ge 2 ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
      done
      for c in "${pids[@]}"; do wait "$c"; done
      grep -h -A20 '^fit:' "$OUT57"/fit_test_*.txt ;;
    ceiling-v57)  # fit-test-v57's fits beside the thirty-sixth bundle's meshes of the same shapes' clean drawings (every
      # test view, mirror averaged: eval-mirror06-clean-v56's record) into OUT57/ceiling.md, and the sheet of
      # CEILING57_SHAPES [the test chairs and tables on three or more supports] (drawing, the bundle's mesh, the fit, the
      # shape) into OUT57/ceiling.png and docs/ceiling_legged.png (seconds)
      local c
      for c in "${LEGS[@]}"; do [ -f "$OUT57/fit_test_$c.json" ] || { step fit-test-v57; break; }; done
      [ -f "$OUT56/mirror06_clean/eval_models_test.json" ] || step eval-mirror06-clean-v56
      [ -f "$OUT56/models_mirror06/router.onnx" ] || step mirror06-v56
      python3 - "$OUT57" "$OUT56/mirror06_clean/eval_models_test.json" "$OUT56/models_mirror06" "$DATA36A" \
        "${CEILING57_SHAPES:-}" "${LEGS[@]}" <<'PY'
import json, sys
from pathlib import Path
from engine.fileio import atomic_write_text
from training.bench.fit import ceiling_rows, ceiling_table
from training.evaluation.gallery import ceiling_sheet
out, ev, models, data, chosen = Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5].split()
cats = sys.argv[6:]
record = json.load(open(ev))
column = next(c for c in record["columns"] if c != "template")
fits = [json.load(open(out / f"fit_test_{c}.json")) for c in cats]
rows = ceiling_rows(fits, record, column)
table = ceiling_table(rows)
f = fits[0]
atomic_write_text(out / "ceiling.md", f"direct fit ({f['views']} views, {f['iters']} iterations, {f['resolution']} px, "
                  f"icosphere level {f['template_level']}, {f['settings'] or 'default settings'}) against {column} "
                  f"({ev}), every test view, clean\n\n{table}\n")
print(table)
if not chosen:  # the legged chairs and tables, whose legs the bundle misses most
    chosen = [r["shape_id"] for r in rows if r["category"] in ("chair", "table") and r["true_supports"] >= 3]
print(ceiling_sheet(models, data, {"direct fit": out / "meshes_test"}, chosen, out / "ceiling.png"))
PY
      cp "$OUT57/ceiling.png" docs/ceiling_legged.png ;;
    overfit-chairs-v57)  # can the predictor learn chairs' legs among chairs? overfit-table-v31's check (the default
      # predictor on true normal images, OVERFIT57_MINUTES [40] min, the cosine over OVERFIT57_ITERS [5600] iterations:
      # what 40 minutes hold on this machine's two cores at 2.4 a second, about 23,000 samples a chair, more than the
      # 17,000 that stood the table on legs among 13 shapes in overfit-long-v32; against each shape's direct fit at
      # damping 4) on the first 8 training chairs (fit-chair-v57's) rendered at the training data's elevations (0, 15,
      # 30, 45; 96 views each), into OUT57/overfit_chairs
      [ -f "$OUT57/chairs8/manifest.json" ] || sketchmesh data --source procedural --categories chair \
        --shapes-per-category 9 --splits train --elevations 0 15 30 45 --out "$OUT57/chairs8"  # index 1 is not a training shape
      sketchmesh bench overfit --set normal_edges=true --out "$OUT57/overfit_chairs" --data "$OUT57/chairs8" --shapes 8 \
        --minutes "${OVERFIT57_MINUTES:-40}" --iters "${OVERFIT57_ITERS:-5600}" --fit-smoothing 4 ;;
    overfit-chair1-v57)  # overfit-table-v31's one-shape check on one chair: chair_00007 (four legs under a ladder back,
      # which its direct fit stands on its four legs, voxel 0.706) alone at the four elevations, 10 min, the cosine over
      # 1,500 iterations (what 10 minutes hold here; the table alone passed with 1,550), into OUT57/overfit_chair1
      [ -f "$OUT57/chair7/manifest.json" ] || sketchmesh data --source procedural --categories chair --first-shape 7 \
        --shapes-per-category 1 --splits train --elevations 0 15 30 45 --out "$OUT57/chair7"
      sketchmesh bench overfit --set normal_edges=true --out "$OUT57/overfit_chair1" --data "$OUT57/chair7" --shapes 1 \
        --minutes 10 --iters 1500 --fit-smoothing 4 ;;
    overfit-chair2-v57)  # overfit-chair1-v57's samples a chair on two chairs together: chair_00002 (three legs) and
      # chair_00003 (four), which their direct fits stand on their own legs, at the four elevations, the cosine over 3,000
      # iterations (48,000 samples each), 21 min at most: do two chairs need more than one's samples each? Into
      # OUT57/overfit_chair2
      [ -f "$OUT57/chair23/manifest.json" ] || sketchmesh data --source procedural --categories chair --first-shape 2 \
        --shapes-per-category 2 --splits train --elevations 0 15 30 45 --out "$OUT57/chair23"
      sketchmesh bench overfit --set normal_edges=true --out "$OUT57/overfit_chair2" --data "$OUT57/chair23" --shapes 2 \
        --minutes 21 --iters 3000 --fit-smoothing 4 ;;
    speed-v58)  # the specialists' CPU training step (recipe20: the larger predictor with its aligned branch, batch 32,
      # half mirrored, the mirror-consistency term; bench train, 3 warm-up and 20 timed steps on DATA36L's generated images)
      # before and after the step's speed-ups: the code of commit BEFORE58 [5370e93] (its engine, training and sketchmesh
      # from git, first on PYTHONPATH) and this one, alternating, twice each (run it alone), into
      # OUT58/bench_train_{before,after}_{1,2}.json; then each run's step and stages side by side
      [ -f "$DATA36L/.cache/generated/normals16_mirror/info.json" ] || step data-val-v56
      local before="$OUT58/code_before" k tag
      rm -rf "$before"; mkdir -p "$before" "$OUT58"
      git archive "${BEFORE58:-5370e93}" engine training sketchmesh | tar -x -C "$before"
      local set=(--set input_normals=normals16 --set mirror=0.5 --set mirror_consistency=50
                 --set mirror_inputs=normals16_mirror --set predictor_aligned=128 --set predictor_channels=64
                 --set predictor_hidden=1024 --set normal_edges=false)
      local code
      for k in 1 2; do
        for tag in before after; do
          code=(sketchmesh); [ "$tag" = before ] && code=(env PYTHONPATH="$before" python3 -P -m sketchmesh)
          "${code[@]}" bench train --data "$DATA36L" --batch 32 --warmup 3 --steps 20 "${set[@]}" \
            --json "$OUT58/bench_train_${tag}_$k.json" > /dev/null
        done
      done
      python3 - "$OUT58" <<'PY'
import json, sys
from pathlib import Path
out = Path(sys.argv[1])
print("| run | step ms (median) | samples/s | predictor fwd / bwd ms | rasterizer + losses ms | CPU ms a step |")
print("|---|---:|---:|---:|---:|---:|")
for k in (1, 2):
    for tag in ("before", "after"):
        r = json.loads((out / f"bench_train_{tag}_{k}.json").read_text())
        st = r["stages_ms"]
        render = sum(st[s] for s in ("rasterizer_forward", "rasterizer_backward", "losses_forward", "losses_backward"))
        print(f"| {tag} {k} | {r['step_ms_median']:.0f} | {r['samples_per_s']:.1f} | "
              f"{st['predictor_forward']:.0f} / {st['predictor_backward']:.0f} | {render:.0f} | {r['step_cpu_ms']:.0f} |")
PY
      ;;
    bundle36-v58)  # the thirty-sixth bundle as shipped (git THIRTYSIXTH [5370e93]) into OUT58/models_bundle36, and its legged
      # specialist beside the twenty-first's generator (git TWENTYFIRST [2a2eadb]) into OUT58/models_bundle_legs: what the
      # v58 steps start from on a machine without the tenth round's run (runs/v54 stayed on the machine that trained it)
      bundle_from_git "${THIRTYSIXTH:-5370e93}" "$OUT58/models_bundle36"
      [ -f "$OUT36/models_twentyfirst/generator.onnx" ] || models_from_git "${TWENTYFIRST:-2a2eadb}" "$OUT36/models_twentyfirst"
      rm -rf "$OUT58/models_bundle_legs"; mkdir -p "$OUT58/models_bundle_legs"
      cp "$OUT36/models_twentyfirst/generator.onnx" "$OUT58/models_bundle_legs/"
      cp "$OUT58/models_bundle36/mesh_predictor_legged.onnx" "$OUT58/models_bundle_legs/mesh_predictor.onnx" ;;
    data-v58)  # 1,200 bench, chair and table shapes a category that no stage has seen (ids 4550-5749, train split, 4 grid
      # views each; rendered in two folders of 600 a category, DATA58N and DATA58M, merged into DATA58), and the fifth
      # generator's images of their drawings and of the flipped drawings; resumes
      local first folder
      for first in 4550 5150; do
        folder=$DATA58N; [ "$first" = 5150 ] && folder=$DATA58M
        sketchmesh data --source procedural --first-shape "$first" --shapes-per-category 600 --categories "${LEGS[@]}" \
          --views 12 --elevations 0 15 30 45 --views-per-shape 4 --splits train --workers 2 --out "$folder"
      done
      [ -f "$DATA58/manifest.json" ] || sketchmesh data merge "$DATA58" "$DATA58N" "$DATA58M"
      [ -f "$OUT8/models_fifth/generator.onnx" ] || step models-fifth-v8
      sketchmesh data generated "$DATA58" --models "$OUT8/models_fifth" --name normals16 --workers 2
      sketchmesh data generated "$DATA58" --models "$OUT8/models_fifth" --name normals16_mirror --mirror --workers 2 ;;
    import-legs-v58)  # the bundled legged specialist (the tenth round's, int8-stored) back as a run
      # (RUNS58/bundle_legs/predictor: its weights made float32, batch norms calibrated on DATA58's generated images)
      [ -f "$OUT58/models_bundle_legs/mesh_predictor.onnx" ] || step bundle36-v58
      [ -f "$DATA58/.cache/generated/normals16_mirror/info.json" ] || step data-v58
      import_run "$OUT58/models_bundle_legs" "$RUNS58/bundle_legs" "$DATA58" ;;
    predictor-v58-legs11)  # the legged specialist's eleventh round with the faster step (speed-v58): the bundled
      # specialist (import-legs-v58) trained on along a new cosine by the rounds' recipe and rate (2e-4) on DATA58 alone
      # (the earlier rounds' shapes are not on this machine; twice a round's fresh shapes instead) into RUNS58/legs11;
      # V36_ITERS [2400], V36_MINUTES [40] at most; resumes
      [ -f "$RUNS58/bundle_legs/predictor/config.json" ] || step import-legs-v58
      V36_ITERS=${V36_ITERS:-2400} V36_MINUTES=${V36_MINUTES:-40} legs_round "$RUNS58/bundle_legs/predictor" "$DATA58" \
        "$RUNS58/legs11" ;;
    check-legs-v58)  # predictor-v58-legs11's run exported as the specialists are (OUT58/models_legs11) and scored beside
      # the twenty-first and the bundled legged specialist (as shipped, int8-stored) on the choice set DATA36C (rendered
      # first where missing), into OUT58/check_legs; then its paired gains
      [ -f "$RUNS58/legs11/config.json" ] || step predictor-v58-legs11
      [ -f "$OUT58/models_bundle_legs/mesh_predictor.onnx" ] || step bundle36-v58
      choice_data "$DATA36C" "${LEGS[@]}"
      legs_check "$OUT58" "$RUNS58/legs11" legs11 "$OUT36/models_twentyfirst" "$OUT58/models_bundle_legs" ;;
    legs11-v58)  # the legged specialist's eleventh round from the bundle (about 55 min on 2 cores from a bare machine)
      for s2 in bundle36-v58 data-v58 import-legs-v58 predictor-v58-legs11 check-legs-v58; do step "$s2"; done ;;
    compact18-v58|eval-compact18-clean-v58|eval-compact18-side-v58|eval-compact18-strong-v58|gallery-compact18-v58|\
        legs11-route-v58|versus-v58|ship-compact18-v58)  # the eleventh round routed, measured and shipped:
      # specialist_route (the thirty-sixth bundle OUT56/models_mirror06 with the round's specialist stored as it stores
      # them; every test sketch paired with that bundle's own evals OUT56/mirror06_<case>)
      specialist_route "$1" legs 58 legs11 compact18 56 mirror06 ;;
    latency-bundle-v59)  # the bundle as shipped (assets/models, the thirty-sixth) timed in the app's path on this session's
      # machine (bundle_latency; run it alone) into OUT59/latency_bundle (run twice here, the first run's files copied
      # to OUT59/latency_bundle_first)
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      bundle_latency assets/models "$OUT59/latency_bundle" ;;
    supports-v59)  # where the legs are lost (bench supports): every test view of a standing bench, chair and table, the
      # supports seen in the true silhouette, the bundled generator's image, the bundled legged specialist's mesh of it
      # and of the true normal image, and the meshes' supports in 3D, into OUT59/supports_legged; SUPPORTS59_MODELS
      # [assets/models] and SUPPORTS59_OUT to measure another folder (e.g. a GPU round's, after compact19-v59)
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      sketchmesh bench supports --data "$DATA36A" --models "${SUPPORTS59_MODELS:-assets/models}" \
        --predictor mesh_predictor_legged.onnx --threads 2 --quiet --out "${SUPPORTS59_OUT:-$OUT59/supports_legged}"
      [ -n "${SUPPORTS59_OUT:-}" ] || cp "$OUT59/supports_legged/supports.png" docs/supports_legged.png ;;  # the card's plot
    supports-general-v59)  # supports-v59 for the bundle's general predictor (mesh_predictor.onnx, the twenty-first's, which
      # drawings the router does not recognise get): what the legged specialist's rounds changed, stage by stage, into
      # OUT59/supports_general
      [ -f "$DATA36A/manifest.json" ] || step data-test-v47
      sketchmesh bench supports --data "$DATA36A" --models assets/models --predictor mesh_predictor.onnx --threads 2 \
        --quiet --out "$OUT59/supports_general" ;;
    predictor-v59-legs-n5e4)  # the legged specialist's eleventh round (predictor-v58-legs11) again with the normal term at a
      # quarter of the paper's weight (lambda_n 0.0005): the silhouette, where the legs are, a larger share of each step;
      # the same start, data, cosine and 2,400 iterations, into RUNS59/legs11_n5e4 (run it alone; resumes)
      [ -f "$RUNS58/bundle_legs/predictor/config.json" ] || step import-legs-v58
      RECIPE_LR=${V36_LR:-2e-4} DATA20=$DATA58 recipe20 "$RUNS58/bundle_legs/predictor" "$RUNS59/legs11_n5e4" \
        "${V36_ITERS:-2400}" "${V36_MINUTES:-45}" 2 0.0005 ;;
    check-legs-n5e4-v59)  # that run exported as the specialists are (OUT59/models_legs11_n5e4) and scored on the choice set
      # beside the eleventh round as trained (OUT58/models_legs11, the control) and the bundled specialist, into
      # OUT59/check_legs_n5e4; then its paired gains
      [ -f "$RUNS59/legs11_n5e4/config.json" ] || step predictor-v59-legs-n5e4
      [ -f "$OUT58/models_legs11/mesh_predictor.onnx" ] || step check-legs-v58
      choice_data "$DATA36C" "${LEGS[@]}"
      round_check "$OUT59" "$RUNS59/legs11_n5e4" legs11_n5e4 "$DATA36C" check_legs_n5e4 "$OUT58/models_bundle_legs" \
        "$OUT58/models_legs11" ;;
    supports-choice-v59)  # bench supports on the choice set's standing shapes (DATA36C, train split: 129 unseen bench, chair
      # and table shapes x 4 views) for the bundled specialist, the eleventh round and the quarter-normal round, into
      # OUT59/supports_choice_<name>
      [ -f "$OUT59/models_legs11_n5e4/mesh_predictor.onnx" ] || step check-legs-n5e4-v59
      local m
      for m in "$OUT58/models_bundle_legs" "$OUT58/models_legs11" "$OUT59/models_legs11_n5e4"; do
        sketchmesh bench supports --data "$DATA36C" --split train --models "$m" --threads 2 --quiet \
          --out "$OUT59/supports_choice_${m##*/models_}"
      done ;;
    predictor-v59-legs-band)  # the legged specialist's eleventh round (predictor-v58-legs11) again with the silhouette
      # term's lowest quarter of rows (legs and the gaps between them) weighing 4 (--support-band-weight 3); the same start,
      # data, cosine and 2,400 iterations, into RUNS59/legs11_band (run it alone; resumes)
      [ -f "$RUNS58/bundle_legs/predictor/config.json" ] || step import-legs-v58
      RECIPE_EXTRA="--support-band-weight ${BAND59:-3}" RECIPE_LR=${V36_LR:-2e-4} DATA20=$DATA58 \
        recipe20 "$RUNS58/bundle_legs/predictor" "$RUNS59/legs11_band" "${V36_ITERS:-2400}" "${V36_MINUTES:-45}" 2 ;;
    check-legs-band-v59)  # that run exported as the specialists are (OUT59/models_legs11_band), scored on the choice set
      # beside the bundled specialist and the eleventh round as trained (the control), into OUT59/check_legs_band, and its
      # supports counted there (bench supports, OUT59/supports_choice_legs11_band)
      [ -f "$RUNS59/legs11_band/config.json" ] || step predictor-v59-legs-band
      [ -f "$OUT58/models_legs11/mesh_predictor.onnx" ] || step check-legs-v58
      choice_data "$DATA36C" "${LEGS[@]}"
      round_check "$OUT59" "$RUNS59/legs11_band" legs11_band "$DATA36C" check_legs_band "$OUT58/models_bundle_legs" \
        "$OUT58/models_legs11"
      sketchmesh bench supports --data "$DATA36C" --split train --models "$OUT59/models_legs11_band" --threads 2 --quiet \
        --out "$OUT59/supports_choice_legs11_band" ;;
    predictor-v59-legs-band1)  # predictor-v59-legs-band at a third of its extra weight (--support-band-weight 1: the lowest
      # quarter of rows weighing 2): whether a milder weight keeps the standing chairs without the IoU it cost; the same
      # start, data, cosine and 2,400 iterations, into RUNS59/legs11_band1 (run it alone; resumes)
      [ -f "$RUNS58/bundle_legs/predictor/config.json" ] || step import-legs-v58
      RECIPE_EXTRA="--support-band-weight ${BAND59B:-1}" RECIPE_LR=${V36_LR:-2e-4} DATA20=$DATA58 \
        recipe20 "$RUNS58/bundle_legs/predictor" "$RUNS59/legs11_band1" "${V36_ITERS:-2400}" "${V36_MINUTES:-45}" 2 ;;
    check-legs-band1-v59)  # that run exported (OUT59/models_legs11_band1), scored on the choice set beside the eleventh round
      # as trained (the control) and at weight 3 (OUT59/models_legs11_band, where check-legs-band-v59 has made it), into
      # OUT59/check_legs_band1, and its supports and the control's counted there (OUT59/supports_choice_<name>)
      [ -f "$RUNS59/legs11_band1/config.json" ] || step predictor-v59-legs-band1
      [ -f "$OUT58/models_legs11/mesh_predictor.onnx" ] || step check-legs-v58
      local band3=(); [ -f "$OUT59/models_legs11_band/mesh_predictor.onnx" ] && band3=("$OUT59/models_legs11_band")
      choice_data "$DATA36C" "${LEGS[@]}"
      round_check "$OUT59" "$RUNS59/legs11_band1" legs11_band1 "$DATA36C" check_legs_band1 "$OUT58/models_legs11" \
        "${band3[@]}"
      local m models=("$OUT59/models_legs11_band1")  # and the control's, where supports-choice-v59 has not counted them
      [ -f "$OUT59/supports_choice_legs11/supports.md" ] || models+=("$OUT58/models_legs11")
      for m in "${models[@]}"; do
        sketchmesh bench supports --data "$DATA36C" --split train --models "$m" --threads 2 --quiet \
          --out "$OUT59/supports_choice_${m##*/models_}"
      done ;;
    gallery-band-v59)  # the meshes behind check-legs-band1-v59's figures: three test chairs and tables (DATA36A's, rendered
      # alone into DATA59G [data/test100e4_legs]), mirror averaged, by the eleventh round (the control), at support band
      # weight 3 (where check-legs-band-v59 has made it) and at weight 1 (OUT59/gallery_<models>.png), and side by side,
      # at half size, as the card's picture (docs/support_band.png)
      local m pngs=() titles=() gal=${DATA59G:-data/test100e4_legs}
      [ -f "$OUT59/models_legs11_band1/mesh_predictor.onnx" ] || step check-legs-band1-v59
      sketchmesh data --source procedural --shapes-per-category 100 --categories chair table --views 12 \
        --elevations 0 15 30 45 --splits test --workers 2 --out "$gal"
      for m in "$OUT58/models_legs11" "$OUT59/models_legs11_band" "$OUT59/models_legs11_band1"; do
        [ -f "$m/mesh_predictor.onnx" ] || continue
        sketchmesh gallery --data "$gal" --models "$m" --categories chair table --per-category 3 --mirror-average \
          --threads 2 -o "$OUT59/gallery_${m##*/models_}.png"
        pngs+=("$OUT59/gallery_${m##*/models_}.png")
        case $m in
          *band) titles+=("support band weight 3") ;;
          *band1) titles+=("support band weight 1") ;;
          *) titles+=("eleventh round (control)") ;;
        esac
      done
      python3 - docs/support_band.png "${#pngs[@]}" "${pngs[@]}" "${titles[@]}" <<'PY'
import sys

from PIL import Image, ImageDraw

from engine.fileio import atomic_open

out, n = sys.argv[1], int(sys.argv[2])
paths, titles = sys.argv[3:3 + n], sys.argv[3 + n:]
ims = [Image.open(p).convert("RGB") for p in paths]
ims = [im.resize((im.width // 2, im.height // 2), Image.LANCZOS) for im in ims]
sheet = Image.new("RGB", (sum(im.width for im in ims), max(im.height for im in ims) + 24), "white")
x = 0
for im, title in zip(ims, titles):
    sheet.paste(im, (x, 24))
    ImageDraw.Draw(sheet).text((x + 8, 6), title, fill="black")
    x += im.width
with atomic_open(out) as fh:
    sheet.save(fh, format="PNG", optimize=True)
print("wrote", out)
PY
      ;;
    whl-gpu)  # the Python packages a lent GPU machine lacks (trimesh, manifold3d), as wheels for its Python 3.12 in .whl
      # (git-ignored; carry it): what training/gpu_predictor.sh installs there first
      python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 -d .whl \
        trimesh==5.2.0 manifold3d==3.5.4
      ls -l .whl ;;
    fetch-gpu-v59)  # what gpu_predictor.sh brought back from the legged specialist's GPU call (GPU_FILES) -> RUNS59/NAME
      RUNS2=$RUNS59 step fetch-gpu ;;
    check-legs-v59)  # that run (RUNS59/GPU59_RUN [legs12]) exported as the specialists are (OUT59/models_gpulegs12) and
      # scored beside the twenty-first and the bundled legged specialist on the choice set DATA36C (rendered first where
      # missing), into OUT59/check_legs; then its paired gains (check-legs-v58's check)
      [ -f "$RUNS59/${GPU59_RUN:-legs12}/config.json" ] || { echo "check-legs-v59: no run $RUNS59/${GPU59_RUN:-legs12}: fetch-gpu-v59 first" >&2; exit 1; }
      [ -f "$OUT58/models_bundle_legs/mesh_predictor.onnx" ] || step bundle36-v58
      choice_data "$DATA36C" "${LEGS[@]}"
      legs_check "$OUT59" "$RUNS59/${GPU59_RUN:-legs12}" gpulegs12 "$OUT36/models_twentyfirst" "$OUT58/models_bundle_legs" ;;
    compact19-v59|eval-compact19-clean-v59|eval-compact19-side-v59|eval-compact19-strong-v59|gallery-compact19-v59|\
        gpulegs12-route-v59|versus-v59|ship-compact19-v59)  # the GPU round routed, measured and shipped as the CPU
      # rounds are (specialist_route against the thirty-sixth bundle's own evals, OUT56/mirror06_<case>)
      specialist_route "$1" legs 59 gpulegs12 compact19 56 mirror06 ;;
    all-v1)
      for s in data normals normals16 mesh silhouette paper-normal joint export eval eval-strong eval-gt tradeoff gallery; do step "$s"; done ;;
    *)
      # the steps are this script's case labels, listed from the script itself so the list cannot go stale
      echo "reproduce_models.sh: unknown step '$1'; the steps: $(grep -oE '^    [a-z0-9|-]+\)' "$0" | tr -d ' )' | tr '|\n' '  ')" >&2
      exit 2 ;;
  esac
}

if [ $# -eq 0 ]; then
  sed -n '2,/^set -euo/{/^set/!p}' "$0"
  exit 2
fi
for s in "$@"; do step "$s"; done
