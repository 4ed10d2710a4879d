// ThermoLab watchdog sketch for the TCLab kit (Arduino Uno/Leonardo with the TCLab shield).
//
// Speaks the TCLab firmware 2.0.1 serial protocol as documented in ThermoLab's notes
// (T1 T2 Q1 Q2 R1 R2 P1 P2 LED SCAN VER X; 115200 baud; a command ends at CR or LF;
// case-insensitive; replies end in CR LF; an unknown command switches both heaters off and
// is echoed upper-cased) and adds one command:
//
//   WDOG n   arm the watchdog for n seconds (0 disarms, at most 3600); reply "Watchdog n s".
//
// The watchdog is armed at power-on (WATCHDOG_DEFAULT_S). When no command has arrived for
// n seconds, both heaters are switched off, so a host that dies (kill -9, a crash, a pulled
// network cable on the server) cannot leave a heater on. Any command, a read included,
// restarts the period; the ThermoLab driver reads the sensor every sample.
//
// Written for ThermoLab from the protocol facts alone (no code of the stock firmware).
// Pins are those of the TCLab shield: heaters on PWM pins 3 and 5, TMP36 sensors on A0 and
// A2, LED on pin 9, a 3.3 V reference on AREF. Check them against your board before flashing.
// Licence: as ThermoLab.

const int HEATER_PIN[2] = {3, 5};
const int SENSOR_PIN[2] = {A0, A2};
const int LED_PIN = 9;
const float AREF_MV = 3300.0;           // TMP36: 10 mV/degC, 500 mV at 0 degC
const unsigned long WATCHDOG_DEFAULT_S = 30;
const unsigned long WATCHDOG_MAX_S = 3600;
const unsigned long LED_OVERRIDE_MS = 10000;

float heater[2] = {0.0, 0.0};           // percent, 0-100
float powerLimit[2] = {255.0, 255.0};   // PWM at 100 %, 0-255
float ledOverride = 0.0;
unsigned long ledUntil = 0;
unsigned long watchdogMs = WATCHDOG_DEFAULT_S * 1000UL;
unsigned long lastCommandMs = 0;
char line[40];
int lineLength = 0;

float clip(float value, float low, float high) {
  return value < low ? low : (value > high ? high : value);
}

void setHeater(int i, float percent) {
  heater[i] = clip(percent, 0.0, 100.0);
  analogWrite(HEATER_PIN[i], (int)(heater[i] / 100.0 * powerLimit[i] + 0.5));
}

void heatersOff() {
  setHeater(0, 0.0);
  setHeater(1, 0.0);
}

float temperature(int i) {
  // Averaging a few conversions steadies the reading; a missing sensor reads code 0 = -50 degC.
  long sum = 0;
  for (int k = 0; k < 10; k++) sum += analogRead(SENSOR_PIN[i]);
  float millivolts = (sum / 10.0) * AREF_MV / 1024.0;
  return (millivolts - 500.0) / 10.0;
}

void reply(float value) {
  Serial.println(value, 3);  // println ends in CR LF
}

void execute(char *command) {
  for (char *c = command; *c; c++) *c = toupper(*c);
  char *argument = strchr(command, ' ');
  float value = 0.0;  // a missing or unreadable value is 0, as atof gives
  if (argument != NULL) {
    *argument = '\0';
    value = atof(argument + 1);
  }
  if (!strcmp(command, "T1") || !strcmp(command, "T2")) {
    reply(temperature(command[1] - '1'));
  } else if (!strcmp(command, "Q1") || !strcmp(command, "Q2")) {
    setHeater(command[1] - '1', value);
    reply(heater[command[1] - '1']);
  } else if (!strcmp(command, "R1") || !strcmp(command, "R2")) {
    reply(heater[command[1] - '1']);
  } else if (!strcmp(command, "P1") || !strcmp(command, "P2")) {
    int i = command[1] - '1';
    powerLimit[i] = clip(value, 0.0, 255.0);
    setHeater(i, heater[i]);
    reply(powerLimit[i]);
  } else if (!strcmp(command, "LED")) {
    ledOverride = clip(value, 0.0, 100.0);
    ledUntil = millis() + LED_OVERRIDE_MS;
    reply(ledOverride);
  } else if (!strcmp(command, "SCAN")) {
    reply(temperature(0));
    reply(temperature(1));
    reply(heater[0]);
    reply(heater[1]);
  } else if (!strcmp(command, "VER")) {
    Serial.println("TCLab Firmware 2.0.1 Arduino (ThermoLab watchdog)");
  } else if (!strcmp(command, "X")) {
    heatersOff();
    Serial.println("Stop");
  } else if (!strcmp(command, "WDOG")) {
    unsigned long seconds = (unsigned long)clip(value, 0.0, WATCHDOG_MAX_S);
    watchdogMs = seconds * 1000UL;
    Serial.print("Watchdog ");
    Serial.print(seconds);
    Serial.println(" s");
  } else {
    heatersOff();
    Serial.println(command);
  }
}

void setup() {
  analogReference(EXTERNAL);
  pinMode(LED_PIN, OUTPUT);
  heatersOff();
  Serial.begin(115200);
  lastCommandMs = millis();
}

void loop() {
  while (Serial.available() > 0) {
    char c = Serial.read();
    if (c == '\r' || c == '\n') {
      line[lineLength] = '\0';
      if (lineLength > 0) {  // the LF of a CR LF pair is an empty command: no reply
        lastCommandMs = millis();
        execute(line);
      }
      lineLength = 0;
    } else if (lineLength < (int)sizeof(line) - 1) {
      line[lineLength++] = c;
    }
  }
  // Unsigned subtraction stays right when millis() wraps (every 49.7 days).
  if (watchdogMs > 0 && millis() - lastCommandMs >= watchdogMs) {
    if (heater[0] > 0.0 || heater[1] > 0.0) heatersOff();
    lastCommandMs = millis();
  }
  bool overridden = (long)(ledUntil - millis()) > 0;
  float led = overridden ? ledOverride : (heater[0] > heater[1] ? heater[0] : heater[1]);
  analogWrite(LED_PIN, (int)(led / 100.0 * 255.0 + 0.5));
}
