# The rig of ../calib-opencv.json as OpenCV's stereo_calib sample stores it with
# cv2.FileStorage: intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml (R T and the
# rectification R1 R2 P1 P2 Q of cv2.stereoRectify), T in millimetres as after a
# calibration with the target's square size given in mm; and stereo.yml, one file
# with cameraMatrix1/distCoeffs1/... (the names of cv2.stereoCalibrate's
# arguments), T in metres and the image size, as YAML and as XML.
# Run from fsw-docs/interfaces/examples: python3 opencv-storage/write.py
import json, numpy as np, cv2
c = json.load(open('calib-opencv.json'))
K1 = np.array(c['left']['K']); D1 = np.array([c['left']['dist']])
K2 = np.array(c['right']['K']); D2 = np.array([c['right']['dist']])
R = np.array(c['R']); T = np.array(c['T']).reshape(3, 1)
W, H = c['image_size']
R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(K1, D1, K2, D2, (W, H), R, T)
def write(name, items):
    fs = cv2.FileStorage('opencv-storage/' + name, cv2.FILE_STORAGE_WRITE)
    for k, v in items:
        fs.write(k, v)
    fs.release()
write('intrinsics.yml', [('M1', K1), ('D1', D1), ('M2', K2), ('D2', D2)])
write('extrinsics.yml', [('R', R), ('T', T * 1000.0), ('R1', R1), ('R2', R2), ('P1', P1), ('P2', P2), ('Q', Q)])
one = [('image_size', np.array([[W, H]], dtype=np.int32)),
       ('cameraMatrix1', K1), ('distCoeffs1', D1),
       ('cameraMatrix2', K2), ('distCoeffs2', D2), ('R', R), ('T', T)]
write('stereo.yml', one)
write('stereo.xml', one)
open('opencv-storage/calib.json', 'w').write(
    '{"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "image_size": [%d, %d], "T_unit": "mm"}\n' % (W, H))
print(cv2.__version__)
