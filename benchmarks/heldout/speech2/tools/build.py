"""Build speech.csv and naming.csv from the hand-annotated source annotated.txt.
Source format: '## speaker', '# place', then 'sentence || name said' (empty = no place name;
several names separated by '; ')."""
import csv, os
HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.dirname(HERE)
rows, spk, place = [], None, None
for line in open(os.path.join(HERE, "annotated.txt"), encoding="utf-8"):
    line = line.rstrip("\n")
    if not line.strip():
        continue
    if line.startswith("## "):
        spk = line[3:].strip(); continue
    if line.startswith("# "):
        place = line[2:].strip(); continue
    sent, name = line.split("||")
    sent, name = sent.strip(), name.strip()
    rows.append((place, spk, sent, "yes" if name else "no", name))
order = ["entrance", "toilet", "bath", "washroom", "kitchen", "dining", "living-room", "bedroom"]
rows.sort(key=lambda r: order.index(r[0]))  # stable: speaker order kept within place
with open(os.path.join(OUT, "speech.csv"), "w", encoding="utf-8", newline="") as f:
    w = csv.writer(f, lineterminator="\n"); w.writerow(["place", "speaker", "sentence"])
    w.writerows(r[:3] for r in rows)
with open(os.path.join(OUT, "naming.csv"), "w", encoding="utf-8", newline="") as f:
    w = csv.writer(f, lineterminator="\n"); w.writerow(["place", "speaker", "sentence", "names_place", "name_said"])
    w.writerows(rows)
print(len(rows), "rows written")
