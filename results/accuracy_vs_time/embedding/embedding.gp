$A << EOD
4.969 0.3906 37.7416 0.375 0.3958 0.3958 0.3958 "D c32 50it"
8.186 0.375 35.7394 0.375 0.375 0.375 0.375 "D c32 100it"
14.865 0.375 33.9693 0.375 0.375 0.375 0.375 "D c32 200it"
28.097 0.375 33.0933 0.375 0.375 0.375 0.375 "D c32 400it"
8.322 0.375 37.6659 0.375 0.375 0.375 0.375 "D c64 50it"
14.159 0.375 36.5184 0.375 0.375 0.375 0.375 "D c64 100it"
26.545 0.375 35.3928 0.375 0.375 0.375 0.375 "D c64 200it"
49.903 0.375 34.0434 0.375 0.375 0.375 0.375 "D c64 400it"
12.547 0.375 38.8881 0.375 0.375 0.375 0.375 "D cframe 50it"
24.578 0.375 36.6197 0.375 0.375 0.375 0.375 "D cframe 100it"
46.608 0.375 34.9106 0.375 0.375 0.375 0.375 "D cframe 200it"
85.693 0.375 33.5139 0.375 0.375 0.375 0.375 "D cframe 400it"
4.484 0.3958 37.4791 0.3958 0.3958 0.3958 0.3958 "- c32 50it"
7.254 0.375 35.6867 0.375 0.375 0.375 0.375 "- c32 100it"
13.34 0.375 34.327 0.375 0.375 0.375 0.375 "- c32 200it"
24.564 0.375 33.5618 0.375 0.375 0.375 0.375 "- c32 400it"
7.442 0.375 37.9037 0.375 0.375 0.375 0.375 "- c64 50it"
13.294 0.375 35.9571 0.375 0.375 0.375 0.375 "- c64 100it"
24.906 0.375 35.0293 0.375 0.375 0.375 0.375 "- c64 200it"
47.606 0.375 33.6394 0.375 0.375 0.375 0.375 "- c64 400it"
11.807 0.375 38.9357 0.375 0.375 0.375 0.375 "- cframe 50it"
22.957 0.375 36.7803 0.375 0.375 0.375 0.375 "- cframe 100it"
44.562 0.375 34.33 0.375 0.375 0.375 0.375 "- cframe 200it"
86.723 0.375 32.7616 0.375 0.375 0.375 0.375 "- cframe 400it"
EOD
$FB << EOD
4.484 0.3958 37.4791 0.3958 0.3958 0.3958 0.3958
4.969 0.3906 37.7416 0.375 0.3958 0.3958 0.3958
7.254 0.375 35.6867 0.375 0.375 0.375 0.375
EOD
$FP << EOD
4.484 0.3958 37.4791 0.3958 0.3958 0.3958 0.3958
4.969 0.3906 37.7416 0.375 0.3958 0.3958 0.3958
7.442 0.375 37.9037 0.375 0.375 0.375 0.375
11.807 0.375 38.9357 0.375 0.375 0.375 0.375
EOD
set terminal pngcairo size 1000,900 font ",10" noenhanced
set output "/work/main/results/accuracy_vs_time/embedding/embedding.png"
set multiplot layout 2,1 title "WATER-GS embedding on demo_scene (1/4 res): BER and PSNR against wall time"
set grid
set xlabel "embedding wall time (s, whole embed command, 1 thread)"
set ylabel "BER (fraction of bits wrong)"
set key outside right
set yrange [0:0.55]
plot $A using 1:4 with points pt 1 ps 1.2 title "identity", \
  $A using 1:5 with points pt 2 ps 1.2 title "gn:0.01", \
  $A using 1:6 with points pt 4 ps 1.2 title "dropout:0.1", \
  $A using 1:7 with points pt 8 ps 1.2 title "crop:0.1", \
  $A using 1:2 with points pt 7 ps 1.3 lc rgb "black" title "mean of the four", \
  $FB using 1:2 with linespoints pt 6 ps 2.4 lw 2 lc rgb "red" title "Pareto front (mean BER)", \
  0.5 with lines dt 2 lc rgb "gray" title "chance"
set ylabel "PSNR vs raw renders (dB)"
set title "points: D = distortion layers on, - = off; c = crop side (frame = whole views); it = iterations" font ",9"
set yrange [*:*]
plot $A using 1:3 with points pt 7 ps 1.3 lc rgb "black" title "points", \
  $A using 1:3:8 with labels offset 0,0.8 font ",8" notitle, \
  $FP using 1:3 with linespoints pt 6 ps 2.4 lw 2 lc rgb "blue" title "Pareto front (PSNR)"
unset multiplot
