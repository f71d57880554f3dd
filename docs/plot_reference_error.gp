# Plots docs/reference_error.csv (tests/bench/bench_reference.sh-style runs against 2048-4096
# spp references, docs/reference.md "Accuracy") to docs/reference_error.png: median per-pixel
# error of `cave shade --view` against `cave reference` versus the bake's CPU time on the
# tess-2 cabin, for 3, 5 and 8 bands with the bounce tail, without and with --split 64 (the
# split costs relight time, not bake time), and the old default (5 bands, no tail); rows with
# the direct light of the sun per pixel (--pixel-lights sun, --split-samples 4; column 13) are
# drawn apart (filled diamonds: --split 64; open diamonds: no split).
#   gnuplot docs/plot_reference_error.gp      (from the repository root)
set datafile separator ","
set terminal pngcairo size 960,600 font "sans,11"
set output "docs/reference_error.png"
set xlabel "bake CPU time [s] (tess-2 cabin, 1024 rays, 2 bounces)"
set ylabel "median per-pixel error against the reference [%]"
set yrange [0:25]
set xrange [15:21]
set grid
set key outside right
set title "End-to-end error, two views x forest/sunset/city (reference noise floor 2.1-4.0%)"
f = "docs/reference_error.csv"
sel(v, m, t, k) = sprintf("< awk -F, '$1==\"%s\" && $2==\"%s\" && $4==2 && $5==%d && $6==%d && $13==\"none\"' %s", v, m, t, k, f)
selp(v, m, k) = sprintf("< awk -F, '$1==\"%s\" && $2==\"%s\" && $6==%d && $13==\"sun\"' %s", v, m, k, f)
L = "driver:forest driver:sunset driver:city seats:forest seats:sunset seats:city"
vw(i) = word(L, i)[1:strstrt(word(L, i), ":") - 1]
mp(i) = word(L, i)[strstrt(word(L, i), ":") + 1:]
pt3(b) = b == 3 ? 6 : (b == 5 ? 7 : 9)
pt64(b) = b == 3 ? 4 : (b == 5 ? 5 : 13)
plot for [i=1:6] sel(vw(i), mp(i), 1, 0) using 7:9:(pt3($3)) with points pt variable ps 1.6 lc i \
       notitle, \
     for [i=1:6] sel(vw(i), mp(i), 1, 64) using 7:9:(pt64($3)) with points pt variable ps 1.6 lc i \
       notitle, \
     for [i=1:6] sel(vw(i), mp(i), 0, 0) using 7:9 with points pt 2 ps 2 lc i notitle, \
     for [i=1:6] selp(vw(i), mp(i), 64) using 7:9 with points pt 15 ps 1.8 lc i notitle, \
     for [i=1:6] selp(vw(i), mp(i), 0) using 7:9 with points pt 14 ps 1.8 lc i notitle, \
     for [i=1:6] NaN with points pt 7 ps 1.6 lc i title word(L, i), \
     NaN with points pt 6 ps 1.6 lc rgb "black" title "3 bands + tail", \
     NaN with points pt 7 ps 1.6 lc rgb "black" title "5 bands + tail", \
     NaN with points pt 9 ps 1.6 lc rgb "black" title "8 bands + tail", \
     NaN with points pt 4 ps 1.6 lc rgb "black" title "3 bands + tail, --split 64", \
     NaN with points pt 5 ps 1.6 lc rgb "black" title "5 bands + tail, --split 64", \
     NaN with points pt 13 ps 1.6 lc rgb "black" title "8 bands + tail, --split 64", \
     NaN with points pt 2 ps 2 lc rgb "black" title "old default (5 bands, no tail)", \
     NaN with points pt 15 ps 1.8 lc rgb "black" title "8 + tail, --split 64, --pixel-lights sun", \
     NaN with points pt 14 ps 1.8 lc rgb "black" title "8 + tail, --pixel-lights sun (default)", \
     5 with lines lc rgb "black" dt 3 title "5% target"
